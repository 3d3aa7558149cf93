"""Fusion's correlation-filter classifier against a NumPy loop reference and scenes with truth."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from jaxtrack.errors import InputError
from jaxtrack.filters.fusion_classifier import (
    PSR_EXCLUSION,
    ClassifierState,
    classifier_params,
    classifier_step,
    init_classifier,
    start_targets,
)

HEIGHT, WIDTH = 96, 128
PATCH = (16, 16)  # small grid: fast tests; the module's default is 32 x 32


def _texture(seed, shape, mean=128.0, spread=100.0, blur=1.0):
    noise = gaussian_filter(np.random.default_rng(seed).normal(size=(*shape, 3)), (blur, blur, 0))
    return (mean + spread * noise / noise.std()).clip(0, 255).astype(np.uint8)


BACKGROUND = _texture(0, (HEIGHT, WIDTH), mean=90.0, spread=20.0, blur=2.0)
TEXTURES = (_texture(1, (24, 16)), _texture(2, (24, 16)))


def _scene(corners, textures=TEXTURES):
    """The background with each texture pasted at its integer top-left corner ``(x, y)``."""
    frame = BACKGROUND.copy()
    for (x, y), texture in zip(corners, textures, strict=False):
        h, w = texture.shape[:2]
        frame[y : y + h, x : x + w] = texture
    return jnp.asarray(frame)


def _boxes(corners):
    return jnp.asarray([[x, y, 16.0, 24.0] for x, y in corners], jnp.float32)


# --- an independent NumPy reference, one slot at a time, with loops --------------------------


def _ref_features(frame, box, scale, shape):
    rows, cols = shape
    frame = np.asarray(frame, np.float64)
    height, width = frame.shape[:2]
    x, y, w, h = (float(v) for v in box)
    cell_x, cell_y = scale * w / cols, scale * h / rows
    x0 = x + w / 2 - (cols // 2 + 0.5) * cell_x
    y0 = y + h / 2 - (rows // 2 + 0.5) * cell_y
    grey = np.empty(shape)
    for i in range(rows):
        for j in range(cols):
            u = min(max(x0 + (j + 0.5) * cell_x - 0.5, 0.0), width - 1.0)
            v = min(max(y0 + (i + 0.5) * cell_y - 0.5, 0.0), height - 1.0)
            u0, v0 = min(int(np.floor(u)), width - 2), min(int(np.floor(v)), height - 2)
            a, b = u - u0, v - v0
            rgb = (1 - b) * ((1 - a) * frame[v0, u0] + a * frame[v0, u0 + 1]) + b * (
                (1 - a) * frame[v0 + 1, u0] + a * frame[v0 + 1, u0 + 1]
            )
            grey[i, j] = 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2]
    f = np.log(1.0 + grey)
    f -= f.mean()
    f /= np.sqrt((f * f).sum())
    for i in range(rows):
        for j in range(cols):
            f[i, j] *= np.sin(np.pi * i / (rows - 1)) ** 2 * np.sin(np.pi * j / (cols - 1)) ** 2
    return f, (cell_x, cell_y)


def _ref_terms(f, sigma):
    rows, cols = f.shape
    g = np.empty(f.shape)
    for i in range(rows):
        for j in range(cols):
            g[i, j] = np.exp(-((i - rows // 2) ** 2 + (j - cols // 2) ** 2) / (2 * sigma**2))
    big_f, big_g = np.fft.fft2(f), np.fft.fft2(g)
    return big_g * np.conj(big_f), (big_f * np.conj(big_f)).real


def _ref_step(a, b, box, frame, p, update):
    """One slot: response, parabola-refined peak, PSR, then the MOSSE running averages."""
    f, (cell_x, cell_y) = _ref_features(frame, box, float(p.search_scale), a.shape)
    response = np.fft.ifft2(np.fft.fft2(f) * a / (b + float(p.regularisation))).real
    rows, cols = response.shape
    i, j = np.unravel_index(np.argmax(response), response.shape)
    shifts = []
    for minus, plus in (
        (response[(i - 1) % rows, j], response[(i + 1) % rows, j]),
        (response[i, (j - 1) % cols], response[i, (j + 1) % cols]),
    ):
        curvature = minus - 2 * response[i, j] + plus
        shifts.append(np.clip((minus - plus) / (2 * curvature), -0.5, 0.5) if curvature < 0 else 0)
    side = [
        response[r, c]
        for r in range(rows)
        for c in range(cols)
        if abs(r - i) > PSR_EXCLUSION or abs(c - j) > PSR_EXCLUSION
    ]
    psr = (response[i, j] - np.mean(side)) / np.std(side)
    moved = np.array(box, np.float64)
    moved[0] += (j + shifts[1] - cols // 2) * cell_x
    moved[1] += (i + shifts[0] - rows // 2) * cell_y
    if update:
        features = _ref_features(frame, moved, float(p.search_scale), a.shape)[0]
        new_a, new_b = _ref_terms(features, float(p.sigma))
        rate = float(p.learning_rate)
        a, b = (1 - rate) * a + rate * new_a, (1 - rate) * b + rate * new_b
    return a, b, moved, response, psr


# --- tests ------------------------------------------------------------------------------------

PARAMS = classifier_params(learning_rate=0.35, sigma=1.0)
# Compiled once per shape for speed; test_jit_equals_eager checks them against eager runs.
STEP = jax.jit(classifier_step)
INIT = jax.jit(init_classifier, static_argnums=4)


def _start(corners, params=PARAMS, alive=None):
    alive = jnp.ones(len(corners), bool) if alive is None else jnp.asarray(alive)
    return INIT(_scene(corners), _boxes(corners), alive, params, PATCH)


@pytest.mark.parametrize("shift", [(3, 0), (-3, 2), (5, -4), (-6, -5), (0, 7), (4, 6), (-7, 0)])
def test_recovers_a_known_translation_within_one_pixel(shift):
    start = [(50, 30)]
    state = INIT(_scene(start), _boxes(start), jnp.ones(1, bool), PARAMS)
    moved = [(50 + shift[0], 30 + shift[1])]
    state, response = STEP(state, _scene(moved), PARAMS, jnp.ones(1, bool))
    np.testing.assert_allclose(state.boxes[0], _boxes(moved)[0], atol=1.0)
    assert float(response.psr[0]) > 5.0


def test_step_matches_a_numpy_loop_reference():
    corners = [(40, 30), (80, 50), (10, 10)]
    state = _start(corners, alive=[True, True, False])
    frame = _scene([(43, 28), (78, 53)])
    update = jnp.array([True, False, True])
    new, response = STEP(state, frame, PARAMS, update)
    for slot in range(2):
        a0, b0 = _ref_terms(
            _ref_features(_scene(corners), _boxes(corners)[slot], 2.0, PATCH)[0], 1.0
        )
        np.testing.assert_allclose(state.numerator[slot], a0, rtol=1e-4, atol=1e-4)
        np.testing.assert_allclose(state.denominator[slot], b0, rtol=1e-4, atol=1e-4)
        a, b, box, r, psr = _ref_step(a0, b0, state.boxes[slot], frame, PARAMS, bool(update[slot]))
        np.testing.assert_allclose(response.response[slot], r, atol=1e-4)
        np.testing.assert_allclose(response.psr[slot], psr, rtol=1e-3)
        np.testing.assert_allclose(new.boxes[slot], box, atol=1e-3)
        np.testing.assert_allclose(new.numerator[slot], a, rtol=1e-4, atol=1e-4)
        np.testing.assert_allclose(new.denominator[slot], b, rtol=1e-4, atol=1e-4)
    # the dead slot: untouched, no response
    np.testing.assert_array_equal(new.boxes[2], state.boxes[2])
    np.testing.assert_array_equal(new.numerator[2], state.numerator[2])
    assert float(jnp.abs(response.response[2]).max()) == 0.0 and float(response.psr[2]) == 0.0


def test_learning_rate_zero_keeps_the_filter_while_the_box_moves():
    params = classifier_params(learning_rate=0.0, sigma=1.0)
    state = _start([(40, 30)], params)
    new, _ = STEP(state, _scene([(44, 32)]), params, jnp.ones(1, bool))
    np.testing.assert_array_equal(new.numerator, state.numerator)
    np.testing.assert_array_equal(new.denominator, state.denominator)
    np.testing.assert_allclose(new.boxes[0, :2], [44, 32], atol=1.0)


def test_frozen_slots_keep_their_filter_and_learning_slots_change():
    corners = [(40, 30), (80, 50)]
    state = _start(corners)
    new, _ = STEP(state, _scene([(42, 31), (82, 49)]), PARAMS, jnp.array([False, True]))
    np.testing.assert_array_equal(new.numerator[0], state.numerator[0])
    np.testing.assert_array_equal(new.denominator[0], state.denominator[0])
    assert float(jnp.abs(new.numerator[1] - state.numerator[1]).max()) > 1e-3
    np.testing.assert_allclose(new.boxes[:, :2], [[42, 31], [82, 49]], atol=1.0)


def test_vmap_over_targets_equals_one_target_at_a_time():
    corners = [(40, 30), (80, 50)]
    frame = _scene([(43, 28), (78, 53)])
    update = jnp.array([True, False])
    both, both_response = STEP(_start(corners), frame, PARAMS, update)
    for slot in range(2):
        single = ClassifierState(*(leaf[slot : slot + 1] for leaf in _start(corners)))
        one, one_response = STEP(single, frame, PARAMS, update[slot : slot + 1])
        for got, want in zip(one, both, strict=True):
            np.testing.assert_allclose(got[0], want[slot], rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(one_response.psr[0], both_response.psr[slot], rtol=1e-6)


def test_jit_equals_eager():
    corners = [(40, 30), (80, 50)]
    state = _start(corners)
    frame = _scene([(43, 28), (78, 53)])
    update = jnp.array([True, False])
    eager = classifier_step(state, frame, PARAMS, update)
    jitted = jax.jit(classifier_step)(state, frame, PARAMS, update)
    for got, want in zip(jax.tree.leaves(jitted), jax.tree.leaves(eager), strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)


def test_two_textured_targets_tracked_over_twenty_frames():
    truth = [
        [(10 + 3 * t, 12 + t // 2) for t in range(21)],  # right along the top, 3 px per frame
        [(100 - 2 * t, 64 - t // 3) for t in range(21)],  # left along the bottom, slightly up
    ]
    first = [truth[0][0], truth[1][0]]
    state = INIT(_scene(first), _boxes(first), jnp.ones(2, bool), PARAMS)
    worst = 0.0
    for t in range(1, 21):
        corners = [truth[0][t], truth[1][t]]
        state, response = STEP(state, _scene(corners), PARAMS, jnp.ones(2, bool))
        worst = max(worst, float(jnp.abs(state.boxes[:, :2] - _boxes(corners)[:, :2]).max()))
        assert float(response.psr.min()) > 10.0
    assert worst < 1.0  # measured 0.84 px


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_psr_high_on_the_moved_target_low_on_its_shuffled_pixels(seed):
    state = INIT(_scene([(50, 30)]), _boxes([(50, 30)]), jnp.ones(1, bool), PARAMS)
    _, on_target = STEP(state, _scene([(53, 32)]), PARAMS, jnp.ones(1, bool))
    pixels = TEXTURES[0].reshape(-1, 3)
    shuffled = pixels[np.random.default_rng(seed).permutation(len(pixels))].reshape(24, 16, 3)
    _, on_shuffled = STEP(
        state, _scene([(53, 32)], textures=(shuffled,)), PARAMS, jnp.ones(1, bool)
    )
    assert float(on_target.psr[0]) > 20.0
    assert float(on_shuffled.psr[0]) < 10.0  # Bolme et al.: below 7 signals a lost target


def test_start_targets_trains_only_the_new_slots():
    state = _start([(40, 30), (10, 10)], alive=[True, False])
    frame = _scene([(40, 30), (80, 50)])
    new = start_targets(
        state, frame, _boxes([(40, 30), (80, 50)]), jnp.array([False, True]), PARAMS
    )
    np.testing.assert_array_equal(new.numerator[0], state.numerator[0])
    np.testing.assert_array_equal(new.alive, [True, True])
    a, b = _ref_terms(_ref_features(frame, (80, 50, 16, 24), 2.0, PATCH)[0], 1.0)
    np.testing.assert_allclose(new.numerator[1], a, rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(new.denominator[1], b, rtol=1e-4, atol=1e-4)


@pytest.mark.parametrize(
    "kwargs",
    [{"learning_rate": 1.5}, {"sigma": 0.0}, {"regularisation": -1.0}, {"search_scale": 0.5}],
)
def test_bad_params_are_refused(kwargs):
    with pytest.raises(InputError):
        classifier_params(**kwargs)


def test_bad_inputs_are_refused():
    corners = [(40, 30)]
    frame, boxes = _scene(corners), _boxes(corners)
    with pytest.raises(InputError, match="alive"):
        init_classifier(frame, boxes, jnp.ones(1, jnp.int32), PARAMS, PATCH)
    with pytest.raises(InputError, match="boxes"):
        init_classifier(frame, boxes[0], jnp.ones(1, bool), PARAMS, PATCH)
    with pytest.raises(InputError, match="patch_shape"):
        init_classifier(frame, boxes, jnp.ones(1, bool), PARAMS, (8, 8))
    with pytest.raises(InputError, match="uint8"):
        init_classifier(frame.astype(jnp.float32), boxes, jnp.ones(1, bool), PARAMS, PATCH)
    with pytest.raises(InputError, match="update_mask"):
        classifier_step(_start(corners), frame, PARAMS, jnp.ones(2, bool))
