"""The paper's sequence table as a suite, and the whole paper run on it (``sim suite``, ``benchmark``).

Run:  .venv/bin/python examples/benchmark_suite.py   (about a minute; writes benchmark-example/)

The suite lists the 34 sequences of the IBISCape paper's ``table:ibiscape_sequences``; ``--scale``
shrinks their durations and image sizes.  The benchmark runs every step of the paper on a suite as
batch jobs (a local process pool here; ``DaskExecutor("tcp://host:8786")`` for a cluster) and
writes one report.  Here: four sequences at a tiny scale, one per step.
"""

# %% the suite: names, presets, sizes at a scale
from pathlib import Path

from ibiscape_eval.sim.suite import scaled_duration_s, scaled_side_px, suite_entries

for scale in (1.0, 0.25, 0.05, 0.002):
    print(f"scale {scale:>6}: runs {scaled_duration_s('slam', scale):>5g} s at "
          f"{scaled_side_px(scale)} px, calibration drives {scaled_duration_s('calibration', scale):g} s "
          f"at {scaled_side_px(scale, 'calibration')} px, still IMU "
          f"{scaled_duration_s('imu', scale) / 3600:.2f} h")
entries = suite_entries(0.002)
print(len(entries), "sequences:", ", ".join(e.name for e in entries[:6]), "...")
print(entries[1], entries[1].config().cameras[0])

# %% generate four of them and run the benchmark (local pool of processes)
from ibiscape_eval.batch import LocalExecutor
from ibiscape_eval.benchmark import run_benchmark
from ibiscape_eval.report.benchmark_report import benchmark_tables, write_benchmark_report

if __name__ == "__main__":  # the pool's worker processes import this file: run only once
    out = Path("benchmark-example")
    subset = ["IMU_calib_1", "SVI_calib_1", "ESVI_slam_dyn_1", "SVI_slam_clear_1"]

    def progress(step: str, done: int, failed: int, remaining: int) -> None:
        if remaining == 0:
            print(f"  {step}: {done} jobs, {failed} failed")

    res = run_benchmark(out, scale=0.002, sequences=subset, executor=LocalExecutor(2),
                        progress=progress)
    print(res)

    # %% the tables (each is also a Markdown and an HTML table) and the report files
    for table in benchmark_tables(res):
        print()
        print(table.to_markdown())
    for f in res.failed():
        print("failed:", f["step"], f["key"], "->", f["error"][:120])
    print("wrote", [str(p) for p in write_benchmark_report(out / "report", res)])
