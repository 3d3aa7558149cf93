"""The command's JAX set-up (:mod:`jaxtrack.pipelines.runtime`): the compilation cache and
XLA's CPU thread pool.

Each case runs in a fresh interpreter: the settings must be made before JAX computes, and
the test process's own are fixed by the conftest. (The CPU devices: ``tests/test_sweep.py``.)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import jax
import pytest

from jaxtrack.pipelines.runtime import CACHE_ENV, THREAD_ENVS, cpu_features

_CACHE_SCRIPT = textwrap.dedent(
    """
    import json, sys
    import jax, jax.numpy as jnp
    from jaxtrack import use_compilation_cache
    events = []
    jax.monitoring.register_event_listener(lambda name, **_: events.append(name))
    folder = use_compilation_cache(sys.argv[1] or None)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0)
    step = jax.jit(lambda x: jnp.cumsum(jnp.sin(x) * 3.0) / (1.0 + x))
    value = step(jnp.linspace(0.0, 1.0, 64, dtype=jnp.float32))
    print(json.dumps({
        "folder": None if folder is None else str(folder),
        "hits": events.count("/jax/compilation_cache/cache_hits"),
        "sum": float(jnp.sum(value)),
    }))
    """
)


def _python(script: str, *args: str, drop=(), timeout: int = 300, **env: str) -> dict:
    """Runs ``script`` in a fresh interpreter on the CPU, with this process's environment less
    the variables ``drop`` plus ``env``; returns the JSON object on its last output line."""
    base = {k: v for k, v in os.environ.items() if k not in drop}
    done = subprocess.run(
        [sys.executable, "-c", script, *args],
        env={**base, "JAX_PLATFORMS": "cpu", **env},
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def _run(path: str, **env: str) -> dict:
    return _python(_CACHE_SCRIPT, path, drop=(CACHE_ENV, "JAX_COMPILATION_CACHE_DIR"), **env)


def test_a_second_process_loads_the_compiled_program_from_the_cache(tmp_path):
    cache = tmp_path / "xla"
    first = _run("", **{CACHE_ENV: str(cache)})
    assert first["folder"] == str(cache) and first["hits"] == 0
    assert any(cache.iterdir())  # the program was written
    second = _run("", **{CACHE_ENV: str(cache)})
    assert second["hits"] >= 1  # ... and loaded: not compiled again
    assert second["sum"] == first["sum"]  # the same machine code, the same numbers


def test_the_cache_is_off_when_disabled_and_the_users_own_is_kept(tmp_path):
    assert _run("", **{CACHE_ENV: ""})["folder"] is None  # JAXTRACK_CACHE_DIR= : no cache
    own = tmp_path / "own"
    kept = _run(str(tmp_path / "ours"), JAX_COMPILATION_CACHE_DIR=str(own))
    assert kept["folder"] is None and not (tmp_path / "ours").exists()
    assert kept["hits"] == 0 and any(own.iterdir())  # JAX used the user's folder
    # an explicit folder wins over the variable
    chosen = _run(str(tmp_path / "given"), **{CACHE_ENV: str(tmp_path / "env")})
    assert chosen["folder"] == str(tmp_path / "given")


def test_no_home_folder_means_no_cache(monkeypatch):
    from pathlib import Path

    import jaxtrack.pipelines.runtime as runtime

    def no_home():
        raise RuntimeError("Could not determine home directory.")

    monkeypatch.delenv(CACHE_ENV, raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.delenv("JAX_COMPILATION_CACHE_DIR", raising=False)
    monkeypatch.setattr(Path, "home", staticmethod(no_home))
    # The test run's own cache (tests/conftest.py) is a user's choice to the function: off
    # here, else it would return None for that reason.
    chosen = jax.config.jax_compilation_cache_dir
    jax.config.update("jax_compilation_cache_dir", None)
    try:
        assert runtime.use_compilation_cache() is None
        assert jax.config.jax_compilation_cache_dir is None  # returned before setting it
    finally:
        jax.config.update("jax_compilation_cache_dir", chosen)


_THREADS_SCRIPT = textwrap.dedent(
    """
    import json, os
    import jax, jax.numpy as jnp
    from jaxtrack import use_cpu_threads
    made = use_cpu_threads()
    again = use_cpu_threads(3)  # the variable is set now: a choice made, kept
    jax.jit(lambda x: jnp.exp(x).sum())(jnp.ones((512, 512))).block_until_ready()
    os.environ.pop("PJRT_NPROC", None)
    late = use_cpu_threads(2)  # the client exists: too late, nothing changes
    tasks = os.listdir("/proc/self/task")
    names = [open(f"/proc/self/task/{t}/comm").read().strip() for t in tasks]
    print(json.dumps({"made": made, "again": again, "late": late,
                      "pool": names.count("tf_XLAEigen")}))
    """
)


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="counts threads in /proc")
@pytest.mark.parametrize(
    ("env", "expected"),
    [
        ({}, {"made": 1, "again": 0, "late": 0, "pool": 1}),
        # the user's own choice is kept (XLA's pool then has that many threads)
        ({"PJRT_NPROC": "2"}, {"made": 0, "again": 0, "late": 0, "pool": 2}),
        ({"NPROC": "3"}, {"made": 0, "again": 0, "late": 0, "pool": 3}),
    ],
)
def test_use_cpu_threads_sizes_xlas_pool_once_and_keeps_the_users_choice(env, expected):
    assert _python(_THREADS_SCRIPT, drop=THREAD_ENVS, **env) == expected


def test_use_cpu_threads_refuses_an_empty_pool():
    from jaxtrack.pipelines.runtime import use_cpu_threads

    with pytest.raises(ValueError, match="at least 1"):
        use_cpu_threads(0)


_TRACK_SCRIPT = textwrap.dedent(
    """
    import hashlib, json, sys
    import jax, numpy as np
    from jaxtrack.filters import default_phd_params, phd_filter, run
    from jaxtrack.io import load_sequence
    seq = load_sequence(sys.argv[1])
    info = seq.info
    params = default_phd_params(info.im_width, info.im_height, info.frame_rate)
    _, out = run(phd_filter(1024), jax.random.key(3), params, seq.detections)
    digest = hashlib.sha256()
    for leaf in jax.tree.leaves((out.tracks, out.log_likelihood, out.mass)):
        digest.update(np.asarray(leaf).tobytes())
    print(json.dumps({"digest": digest.hexdigest(), "boxes": int(np.sum(out.tracks.mask))}))
    """
)


def test_the_thread_pool_changes_no_result(mot15_root):
    """The PHD tracker on TUD-Campus with XLA's pool at one thread and at two: the same
    boxes, masses and log-likelihoods, bit for bit (the pool runs a kernel's parts, it does
    not change them)."""
    sequence = str(mot15_root / "TUD-Campus")
    runs = [
        _python(_TRACK_SCRIPT, sequence, drop=THREAD_ENVS, timeout=600, PJRT_NPROC=threads)
        for threads in ("1", "2")
    ]
    assert runs[0]["boxes"] > 0
    assert runs[0] == runs[1]


_WIDTH_SCRIPT = textwrap.dedent(
    """
    import json, os
    import jax, jax.numpy as jnp
    from jaxtrack import use_cpu_vector_width
    from jaxtrack.pipelines.runtime import cpu_vector_width
    made = use_cpu_vector_width()
    again = use_cpu_vector_width(256)  # XLA_FLAGS names a width now: a choice made, kept
    jax.jit(lambda x: jnp.exp(x).sum())(jnp.ones((64, 64))).block_until_ready()
    flags = os.environ.get("XLA_FLAGS", "")
    os.environ["XLA_FLAGS"] = ""
    late = use_cpu_vector_width()  # the backends exist: too late, nothing changes
    os.environ["XLA_FLAGS"] = flags
    print(json.dumps({"made": made, "again": again, "late": late, "width": cpu_vector_width(),
                      "flags": flags}))
    """
)


@pytest.mark.skipif(
    "avx512f" not in cpu_features(), reason="asks for 512-bit vectors only with AVX-512"
)
def test_use_cpu_vector_width_adds_the_flag_once_and_keeps_the_users_choice():
    made = _python(_WIDTH_SCRIPT, XLA_FLAGS="--xla_cpu_enable_fast_min_max=false")
    assert made == {
        "made": 512,
        "again": 0,
        "late": 0,
        "width": 512,
        "flags": "--xla_cpu_enable_fast_min_max=false --xla_cpu_prefer_vector_width=512",
    }
    both = _python(_WIDTH_SCRIPT, drop=("XLA_FLAGS",))
    assert both["flags"] == ("--xla_cpu_prefer_vector_width=512 --xla_cpu_enable_fast_min_max=true")
    kept = _python(_WIDTH_SCRIPT, XLA_FLAGS="--xla_cpu_prefer_vector_width=256")
    assert kept["made"] == 0 and kept["width"] == 256


def test_use_cpu_vector_width_refuses_other_widths():
    from jaxtrack.pipelines.runtime import use_cpu_vector_width

    with pytest.raises(ValueError, match="256, 512"):
        use_cpu_vector_width(128)


@pytest.mark.skipif(
    "avx512f" not in cpu_features(), reason="the wider vectors need AVX-512 registers"
)
def test_the_vector_width_changes_no_result(mot15_root):
    """The PHD tracker on TUD-Campus with XLA's default code generation and with the
    command's (512-bit vectors, plain min/max): the same boxes, masses and log-likelihoods,
    bit for bit (measured on the eleven MOT15 training sequences; README, "Where the PHD
    step's time goes")."""
    sequence = str(mot15_root / "TUD-Campus")
    wide = "--xla_cpu_prefer_vector_width=512 --xla_cpu_enable_fast_min_max=true"
    runs = [
        _python(_TRACK_SCRIPT, sequence, drop=("XLA_FLAGS",), timeout=600, **env)
        for env in ({}, {"XLA_FLAGS": wide})
    ]
    assert runs[0]["boxes"] > 0
    assert runs[0] == runs[1]
