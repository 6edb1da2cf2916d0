"""Start-up of the commands that only list or check: wall time beside ``import typer``.

Times, as fresh processes (best of 5 each, alternating), ``python -c "import typer"`` (the
floor: the CLI framework alone), ``microfab --help``, ``microfab kinds`` and ``microfab run
BROKEN.toml --check`` (a TOML syntax error), and prints each with its ratio to the floor
and the machine's load average (goal: each <= 1 s on an idle 2-core machine). The
commands run through the ``microfab`` console script beside this interpreter, as a user
runs them.

Run: ``python benchmarks/bench_cli.py [repeats]``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def wall(cmd: list[str], cwd: Path) -> float:
    """Wall time of one run of ``cmd``, s (it must exit 0 or 2, the refusal code)."""
    t0 = time.perf_counter()
    res = subprocess.run(cmd, cwd=cwd, capture_output=True, check=False)
    dt = time.perf_counter() - t0
    if res.returncode not in (0, 2):
        raise RuntimeError(f"{cmd} exited {res.returncode}: {res.stderr.decode()[-500:]}")
    return dt


def main(repeats: int = 5) -> None:
    py = sys.executable
    mf = str(Path(py).parent / "microfab")
    with tempfile.TemporaryDirectory() as tmp:
        cwd = Path(tmp)
        (cwd / "broken.toml").write_text("[job\nkind = 'msl-ilc'\n", encoding="utf-8")
        cases = {
            'python -c "import typer"': [py, "-c", "import typer"],
            "microfab --help": [mf, "--help"],
            "microfab kinds": [mf, "kinds"],
            "microfab run BROKEN.toml --check": [mf, "run", "broken.toml", "--check"],
        }
        load = os.getloadavg()
        best = {name: float("inf") for name in cases}
        for cmd in cases.values():  # warm the file cache once
            wall(cmd, cwd)
        for _ in range(repeats):
            for name, cmd in cases.items():
                best[name] = min(best[name], wall(cmd, cwd))
    floor = best['python -c "import typer"']
    print(
        f"load average before: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} ({os.cpu_count()} cores)"
    )
    print(f"{'command':<36} {'best wall [s]':>14} {'x import typer':>15}  goal <= 1 s")
    for name, t in best.items():
        ok = "" if name.startswith("python") else ("ok" if t <= 1.0 else "OVER")
        print(f"{name:<36} {t:14.3f} {t / floor:15.1f}  {ok}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
