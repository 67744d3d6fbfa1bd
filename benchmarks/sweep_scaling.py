"""Does a sweep's cost per point stay flat as the sweep grows? ``stereosim sweep`` in estimate
mode at 100 and at 1,600 points.

Each point is an analytic estimate (milliseconds of work) of a synthetic WxH scene, so the time is
mostly the sweep's own: planning, Dask scheduling, appending each row to ``results.csv`` under the
folder lock and the one final ordered rewrite. The grid is fifo.nna_to_sva_depth x
sva.disparities (10 x 10 and 100 x 16). Both sweeps run on one warmed-up local cluster (imports
and the numba cache load once per worker), each into a fresh output folder; the figure is wall
seconds / points at each size and their ratio (target: the cost at 1,600 within 1.5x of the cost
at 100). Before rows were appended, the whole CSV was rewritten and fsynced after every task, and
1,600 points took 290 s.

    PYTHONPATH=. python benchmarks/sweep_scaling.py [--workers 2] [--size 320x24]

(run from the repository root; PYTHONPATH=. makes sure this checkout's ``sim`` is measured, not
another one installed in editable mode -- the first line printed names the code measured).
"""

from __future__ import annotations

import argparse
import logging
import os
import tempfile
import time
from pathlib import Path

from distributed import Client, LocalCluster

import stereosim
from stereosim.core.config import LEGAL_DISPARITIES
from stereosim.sim.sweep import load_sweep, run_sweep, run_task
from stereosim.sim.sweep_results import CSV_NAME, read_rows

SIZES = {100: (10, 10), 1600: (100, 16)}  # points: (FIFO depths, disparities)


def _sweep_file(folder: Path, points: int, size: str) -> Path:
    n_depths, n_disp = SIZES[points]
    depths = ", ".join(str(8 + i) for i in range(n_depths))
    disps = ", ".join(str(d) for d in LEGAL_DISPARITIES[:n_disp])
    path = folder / f"scaling_{points}.toml"
    path.write_text(
        f'mode = "estimate"\nscenes = ["{size}"]\n[grid]\n'
        f'"fifo.nna_to_sva_depth" = [{depths}]\n"sva.disparities" = [{disps}]\n'
    )
    return path


def _timed(client, folder: Path, points: int, size: str) -> float:
    t0 = time.perf_counter()
    sweep = load_sweep(_sweep_file(folder, points, size))
    counts = run_sweep(sweep, folder / f"out{points}", client=client, progress=False)
    seconds = time.perf_counter() - t0
    assert counts["ok"] == points == len(sweep.tasks), counts
    rows = read_rows(folder / f"out{points}" / CSV_NAME)
    assert [int(r["point"]) for r in rows] == list(range(points))
    return seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--size", default="320x24", help="synthetic scene WxH (W > 256)")
    args = ap.parse_args()
    cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                           host="127.0.0.1", dashboard_address=None,
                           scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                           silence_logs=logging.CRITICAL + 10)
    with Client(cluster) as client, tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        warm = load_sweep(_sweep_file(folder, 100, args.size)).tasks[0]
        client.gather([client.submit(run_task, warm, pure=False, workers=[w])
                       for w in client.scheduler_info()["workers"]])
        seconds = {n: _timed(client, folder, n, args.size) for n in SIZES}
    cluster.close()
    per_point = {n: s / n for n, s in seconds.items()}
    print(f"estimate-mode sweeps of a {args.size} scene on {args.workers} warmed-up local "
          f"workers, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} at the end "
          f"(code: {Path(stereosim.__file__).parent})")
    for n, s in seconds.items():
        print(f"{n:5d} points: {s:7.2f} s, {1e3 * per_point[n]:6.2f} ms a point")
    ratio = per_point[1600] / per_point[100]
    print(f"per-point cost at 1,600 / at 100: {ratio:.2f}x (target <= 1.5x)")


if __name__ == "__main__":
    main()
