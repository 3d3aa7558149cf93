"""Where the PHD tracker's time goes inside its ``lax.scan``, from XLA's own profile.

Runs the tracker as ``benchmarks/phd_sequence.py`` does (PETS09-S2L1, 2048 particles, its own
detection slots, one jitted ``run``) under ``jax.profiler`` and reads the trace: every kernel
XLA launched (a fusion, a sort, a YNNPACK call...), how often and for how long. Each kernel is
attributed to the step's stage through the compiled program's stack frames (the Python line
that made its first instruction): the function the PHD step (``phd._frame_step``) called,
e.g. ``phd_update``, ``_joint_draws`` (the random draws), ``resample``, ``label_step``;
``(step)`` for the step's own lines and ``(unattributed)`` for the copies, constants and
broadcasts XLA made without a source line. A ``while``, ``conditional`` or ``call`` kernel is
counted by its body's kernels, not twice.

Prints, per frame: the kernels launched and their time by stage, then the costliest kernels,
and one JSON object on its last line. The profiler adds its own cost to every kernel (on 2
cores about 1 us), so the traced times add up to more than the untraced run
(``untraced_us_per_frame``, the median of ``--repeats`` runs): compare stages, not totals.
Usage: ``python benchmarks/phd_trace.py [--particles N] [--top 30] [--cpu-threads N]``
(XLA's CPU thread pool as the ``jaxtrack`` command sizes it for the PHD tracker, one thread,
unless ``--cpu-threads`` says otherwise; 0: XLA's default, one per core).
"""

from __future__ import annotations

import collections
import gzip
import json
import re
import tempfile
import time
from pathlib import Path

import jax
import numpy as np
from timing import phd_run_parser, sequence_with_phd_params, set_cpu_threads, set_cpu_vector_width

from jaxtrack.filters import phd_filter, run

#: Kernels whose trace event spans their body's kernels (counted by those instead).
WRAPPERS = ("while", "conditional", "call")
#: The PHD step's function, below which the stage is read.
STEP_FUNCTION = "_frame_step"


def stack_index(hlo: str) -> dict[int, list[tuple[str, str, int]]]:
    """``stack_frame_id -> [(file, function, line), ...]`` (innermost first) from the
    compiled program's text (its ``FileNames``, ``FunctionNames``, ``FileLocations`` and
    ``StackFrames`` tables; a frame's ``parent_frame_id`` is its parent's id plus one, 0 or
    1 for none)."""
    tables: dict[str, dict[int, str]] = collections.defaultdict(dict)
    section = None
    for line in hlo.splitlines():
        if line in ("FileNames", "FunctionNames", "FileLocations", "StackFrames"):
            section = line
            continue
        match = re.match(r"(\d+) (.*)", line)
        if section and match:
            tables[section][int(match.group(1))] = match.group(2)
        elif section == "StackFrames" and not line.strip():
            break
    files = {k: Path(v.strip('"')).name for k, v in tables["FileNames"].items()}
    functions = {k: v.strip('"') for k, v in tables["FunctionNames"].items()}
    locations = {}
    for key, text in tables["FileLocations"].items():
        fields = dict(re.findall(r"(\w+)=(\d+)", text))
        locations[key] = (
            files[int(fields["file_name_id"])],
            functions[int(fields["function_name_id"])],
            int(fields["line"]),
        )
    frames = {}
    for key, text in tables["StackFrames"].items():
        fields = dict(re.findall(r"(\w+)=(\d+)", text))
        frames[key] = (int(fields["file_location_id"]), int(fields.get("parent_frame_id", 0)) - 1)

    def stack(frame: int) -> list[tuple[str, str, int]]:
        out, seen = [], set()
        while frame in frames and frame not in seen:
            seen.add(frame)
            location, frame = frames[frame]
            out.append(locations[location])
        return out

    return {frame: stack(frame) for frame in frames}


def stage_of(stack: list[tuple[str, str, int]]) -> str:
    """The function the PHD step called on the way to this kernel (``(step)`` for the step's
    own lines, ``(outside the step)`` for the scan's and the run's)."""
    for depth, (_, function, _) in enumerate(stack):
        if function == STEP_FUNCTION:
            return stack[depth - 1][1].split(".")[-1] if depth else "(step)"
    return "(outside the step)"


def kernel_stages(hlo: str) -> dict[str, tuple[str, str]]:
    """Instruction name -> (stage, innermost ``file:function:line``) for every instruction
    with a stack frame."""
    stacks = stack_index(hlo)
    out = {}
    pattern = r"^\s*(?:ROOT )?%([\w.\-]+) = .*?stack_frame_id=(\d+)"
    for match in re.finditer(pattern, hlo, re.M):
        stack = stacks.get(int(match.group(2)), [])
        where = ":".join(map(str, stack[0])) if stack else ""
        out.setdefault(match.group(1), (stage_of(stack), where))
    return out


def main() -> None:
    parser = phd_run_parser(__doc__.splitlines()[0], repeats=5)
    parser.add_argument("--top", type=int, default=25, help="costliest kernels printed")
    args = parser.parse_args()
    cpu_threads = set_cpu_threads(args.cpu_threads)
    vector_width = set_cpu_vector_width(args.vector_width)

    sequence, params = sequence_with_phd_params(args.sequence)
    info = sequence.info
    filt = phd_filter(args.particles)
    track = jax.jit(lambda key: run(filt, key, params, sequence.detections)[1].tracks)
    hlo = _compiled_text(track)
    kernels = set(re.findall(r"^\s*(?:ROOT )?%([\w.\-]+) = ", hlo, re.M))
    stages = kernel_stages(hlo)
    jax.block_until_ready(track(jax.random.key(0)))
    times = []
    for repeat in range(args.repeats):
        start = time.perf_counter()
        jax.block_until_ready(track(jax.random.key(repeat + 1)))
        times.append(time.perf_counter() - start)
    frames = sequence.num_frames

    with tempfile.TemporaryDirectory() as folder:
        with jax.profiler.trace(folder, create_perfetto_trace=True):
            jax.block_until_ready(track(jax.random.key(args.repeats + 1)))
        (trace_file,) = Path(folder).rglob("*.trace.json.gz")
        events = json.loads(gzip.open(trace_file).read())["traceEvents"]

    per_kernel: dict[str, list[float]] = collections.defaultdict(lambda: [0.0, 0])
    for event in events:
        name = event.get("name", "")
        if event.get("ph") != "X" or name not in kernels or name.startswith(WRAPPERS):
            continue
        per_kernel[name][0] += event["dur"]
        per_kernel[name][1] += 1
    per_stage: dict[str, list[float]] = collections.defaultdict(lambda: [0.0, 0])
    for name, (micros, count) in per_kernel.items():
        stage = stages.get(name, ("(unattributed)", ""))[0]
        per_stage[stage][0] += micros
        per_stage[stage][1] += count
    traced = sum(micros for micros, _ in per_stage.values())
    launches = sum(count for _, count in per_stage.values())

    print(
        f"{info.name}, {args.particles} particles, {frames} frames, XLA pool {cpu_threads}, "
        f"vector width {vector_width or 'default'}"
    )
    print(f"untraced: {1e6 * np.median(times) / frames:.1f} us per frame")
    print(
        f"traced kernels: {traced / frames:.1f} us and {launches / frames:.0f} launches per frame"
    )
    print(f"{'stage':<22} {'us/frame':>9} {'share':>7} {'kernels/frame':>14}")
    for stage, (micros, count) in sorted(per_stage.items(), key=lambda kv: -kv[1][0]):
        share = 100 * micros / traced
        print(f"{stage:<22} {micros / frames:9.1f} {share:6.1f}% {count / frames:14.1f}")
    print("\ncostliest kernels (us per frame, launches per frame, stage, innermost source):")
    ranked = sorted(per_kernel.items(), key=lambda kv: -kv[1][0])[: args.top]
    for name, (micros, count) in ranked:
        stage, where = stages.get(name, ("(unattributed)", ""))
        print(f"  {micros / frames:7.2f} {count / frames:5.1f}  {name:<34} {stage:<16} {where}")
    print(
        json.dumps(
            {
                "benchmark": "phd_trace",
                "sequence": info.name,
                "num_particles": args.particles,
                "num_frames": frames,
                "cpu_threads": cpu_threads,
                "cpu_vector_width": vector_width,
                "untraced_us_per_frame": 1e6 * float(np.median(times)) / frames,
                "traced_us_per_frame": traced / frames,
                "kernel_launches_per_frame": launches / frames,
                "stages_us_per_frame": {k: v[0] / frames for k, v in per_stage.items()},
                "stages_launches_per_frame": {k: v[1] / frames for k, v in per_stage.items()},
                "jax_version": jax.__version__,
            }
        )
    )


def _compiled_text(jitted) -> str:
    """The optimised program XLA runs (its stack-frame tables included)."""
    return jitted.lower(jax.random.key(0)).compile().as_text()


if __name__ == "__main__":
    main()
