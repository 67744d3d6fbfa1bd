"""Parallel speed-up of ``stereosim sweep``: the same sweep on 1 and on 2 local Dask workers.

Each worker is warmed up first (imports and the numba cache load once per process), so the
figure is the sweep's own scaling: wall time on 1 worker / wall time on 2 workers (target
>= 1.7x). For reference it also times the same runs on a plain process pool, which shows how
much parallelism the machine offers at the moment (on a shared machine, less than its CPUs). Every
point is a cycle-model run of a synthetic 960x540 frame with the CNN descriptor.

    python benchmarks/sweep_speedup.py [--points 16]
"""

from __future__ import annotations

import argparse
import logging
import os
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from distributed import Client, LocalCluster

from stereosim.sim.sweep import load_sweep, run_sweep, run_task


def _sweep_file(folder: Path, points: int) -> Path:
    path = folder / "speedup.toml"
    depths = ", ".join(str(16 + 8 * i) for i in range(points))
    path.write_text(
        'mode = "cycle"\nscenes = ["960x540"]\n[set]\n"nna.descriptor" = "cnn"\n'
        f'"sva.disparities" = 64\n[grid]\n"fifo.nna_to_sva_depth" = [{depths}]\n'
    )
    return path


def _timed(sweep, workers: int, folder: Path) -> float:
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           host="127.0.0.1", dashboard_address=None, silence_logs=logging.ERROR)
    with Client(cluster) as client:
        # warm-up: one small task per worker (imports, numba cache)
        warm = [client.submit(run_task, sweep.tasks[0], pure=False, workers=[w])
                for w in client.scheduler_info()["workers"]]
        client.gather(warm)
        t0 = time.perf_counter()
        counts = run_sweep(sweep, folder / f"out{workers}", client=client, progress=False)
        seconds = time.perf_counter() - t0
    cluster.close()
    assert counts["ok"] == len(sweep.tasks), counts
    return seconds


def _pool_seconds(sweep, workers: int) -> float:
    """The same tasks on a plain process pool (warmed up): what the machine allows right now."""
    with ProcessPoolExecutor(max_workers=workers) as pool:
        list(pool.map(run_task, [sweep.tasks[0]] * workers))
        t0 = time.perf_counter()
        list(pool.map(run_task, sweep.tasks))
        return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=16)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        sweep = load_sweep(_sweep_file(folder, args.points))
        one = _timed(sweep, 1, folder)
        two = _timed(sweep, 2, folder)
        pool_one = _pool_seconds(sweep, 1)
        pool_two = _pool_seconds(sweep, 2)
    load = os.getloadavg()[0]
    print(f"sweep of {len(sweep.tasks)} cycle-model runs (960x540, CNN), {os.cpu_count()} CPUs, "
          f"load average {load:.2f} at the end")
    print(f"1 worker : {one:6.2f} s")
    print(f"2 workers: {two:6.2f} s")
    print(f"speed-up : {one / two:.2f}x (target >= 1.7x)")
    print(f"reference: the same runs on a plain process pool, 1 vs 2 processes: {pool_one:.2f} s"
          f" / {pool_two:.2f} s = {pool_one / pool_two:.2f}x (the parallelism the machine "
          "offers now; other jobs share its cores)")


if __name__ == "__main__":
    main()
