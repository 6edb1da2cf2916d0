"""Wall time of a generic sweep: in this process against a dask LocalCluster of 2 workers.

Run: ``python benchmarks/bench_sweep.py [points] [seconds_per_point]`` (default 8 points of
about 0.5 s of pure-Python arithmetic each). Prints the in-process time, the cluster
start-up and shut-down overhead, the sweep time on an already running cluster, the time
when :func:`run_sweep` starts and closes its own cluster, and the speed-ups, all measured
in the same run.
"""

from __future__ import annotations

import logging
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from typing import Any

from _timing import timed

from microfab.io.sweep import grid, run_sweep

WORKERS = 2


@dataclass(frozen=True)
class Burn:
    index: int
    loops: int


def burn(p: Burn) -> dict[str, Any]:
    """CPU-bound pure-Python loop (holds the GIL, so threads would not help)."""
    t0, c0 = time.perf_counter(), time.process_time()
    acc = 0
    for i in range(p.loops):
        acc = (acc + i * i) % 1_000_003
    return {"acc": acc, "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}


def _loops_for(seconds: float) -> int:
    n = 200_000
    t0 = time.perf_counter()
    burn(Burn(index=0, loops=n))
    return max(1, round(n * seconds / (time.perf_counter() - t0)))


def _timed(label: str, fn: Any) -> float:
    wall, res = timed(fn)
    ran = [r for r in res.rows if r["index"] not in {p.index for p in res.skipped}]
    share = sum(r["cpu_s"] for r in ran) / max(sum(r["wall_s"] for r in ran), 1e-9)
    mean = sum(r["wall_s"] for r in ran) / max(len(ran), 1)
    note = f"  (task {mean:4.2f} s each, {share:4.0%} of a core)" if ran else ""
    print(f"{label:<52s} {wall:7.2f} s{note}")
    return wall


def main() -> None:
    from distributed import Client, LocalCluster

    n_points = int(sys.argv[1]) if len(sys.argv) > 1 else 8
    per_point = float(sys.argv[2]) if len(sys.argv) > 2 else 0.5
    loops = _loops_for(per_point)
    points = grid(Burn, index=range(n_points), loops=[loops])
    print(f"{n_points} points of ~{per_point:g} s ({loops} loop iterations each),")
    print(
        f"{WORKERS} workers, 1 thread each; {os.cpu_count()} cores, load average "
        f"{os.getloadavg()[0]:.2f} (other processes skew the figures)\n"
    )

    with tempfile.TemporaryDirectory() as tmp:
        serial = _timed(
            "in-process (workers=1, no Dask)",
            lambda: run_sweep(burn, points, results_dir=f"{tmp}/serial"),
        )

        t0 = time.perf_counter()
        cluster = LocalCluster(
            n_workers=WORKERS,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            scheduler_kwargs={"dashboard_address": ":0"},
            silence_logs=logging.CRITICAL,
        )
        client = Client(cluster)
        start = time.perf_counter() - t0
        print(f"{'cluster start-up (LocalCluster + Client)':<52s} {start:7.2f} s")
        warm = _timed(
            "on the running cluster (client=)",
            lambda: run_sweep(burn, points, results_dir=f"{tmp}/warm", client=client),
        )
        t0 = time.perf_counter()
        client.close()
        cluster.close()
        stop = time.perf_counter() - t0
        print(f"{'cluster shut-down':<52s} {stop:7.2f} s")

        own = _timed(
            f"run_sweep(workers={WORKERS}) starting and closing its cluster",
            lambda: run_sweep(burn, points, results_dir=f"{tmp}/own", workers=WORKERS),
        )
        resume = _timed(
            "rerun of a finished sweep (all points skipped)",
            lambda: run_sweep(burn, points, results_dir=f"{tmp}/own", workers=WORKERS),
        )

    print()
    print(f"speed-up on the running cluster:       {serial / warm:5.2f}x (ideal {WORKERS}x)")
    print(f"speed-up including cluster start/stop: {serial / own:5.2f}x")
    print(f"overhead of the own cluster:           {own - warm:5.2f} s (start+stop+spread)")
    print(f"resume check time:                     {resume * 1e3:5.1f} ms")


if __name__ == "__main__":  # workers are spawned processes: keep this guard
    main()
