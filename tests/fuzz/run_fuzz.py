"""``make fuzz``: run at least 10 000 generated inputs through the ``microfab`` CLI.

Generates the cases of every kind in `fuzz_cases` with hypothesis (seeded), runs them in
worker processes (`fuzz_driver.run_pool`, 20 s of CPU time per case: a hang is measured
in CPU time or its absence, not in wall time, so load does not make one) and prints the
table: per kind and in total, cases, clean refusals (exit 2, one line starting
``error:``, files left as they were), accepted, uncaught exceptions, hangs, messy
refusals and refusals that changed files. Exits 1 when any case ended in one of the last
four.

    python tests/fuzz/run_fuzz.py                    # 10 000 cases, seed 0, all cores
    python tests/fuzz/run_fuzz.py --cases 2000 --kinds dxf,svg --seed 3 --show 20
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fuzz_cases import KINDS
from fuzz_driver import TIMEOUT_S, Case, Outcome, format_table, run_pool
from hypothesis import HealthCheck, Phase, given, seed, settings


def generate(kind: str, n: int, seed_: int) -> list[Case]:
    """``n`` cases of ``kind`` from its hypothesis strategy (fewer if it runs dry)."""
    strategy = KINDS[kind][0]()
    cases: list[Case] = []

    @seed(seed_)
    @settings(
        max_examples=n,
        database=None,
        deadline=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(strategy)
    def collect(case: Case) -> None:
        cases.append(case)

    collect()
    return cases


def _signature(r: Outcome) -> str:
    """What a failure looks like, without the file names and numbers that vary."""
    first = r.detail.splitlines()[0] if r.detail else r.outcome
    if r.outcome == "uncaught":
        tb = [ln.strip() for ln in r.detail.splitlines() if ln.strip().startswith("File ")]
        where = tb[-1] if tb else ""
        return f"{first.split(':')[0]} at {where}"
    if r.outcome == "dirty":
        return "changed " + ", ".join(r.changed)
    return re.sub(r"[-+]?\d[\d.e+-]*", "N", first)[:120]


def main(argv: list[str] | None = None) -> int:
    """Run the fuzz suite; 0 when nothing crashed, hung or refused untidily."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cases", type=int, default=10_000, help="total cases (default 10000)")
    p.add_argument("--seed", type=int, default=0, help="hypothesis seed (default 0)")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 2)
    p.add_argument(
        "--timeout",
        type=float,
        default=TIMEOUT_S,
        help=f"CPU seconds per case, and seconds without progress ({TIMEOUT_S:g})",
    )
    p.add_argument("--kinds", default=",".join(KINDS), help="comma-separated kinds")
    p.add_argument("--show", type=int, default=20, help="kinds of failure printed (20)")
    p.add_argument("--slow", action="store_true", help="print the three slowest cases")
    p.add_argument("--tracebacks", action="store_true", help="print whole tracebacks")
    p.add_argument("--save", type=Path, help="write each failing case's files here")
    p.add_argument(
        "--accepted", type=Path, help="write the accepted cases here, one line each, by kind"
    )
    args = p.parse_args(argv)

    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    unknown = sorted(set(kinds) - set(KINDS))
    if unknown:
        p.error(f"unknown kinds {unknown}; known: {', '.join(KINDS)}")
    share = sum(KINDS[k][1] for k in kinds)
    t0 = time.monotonic()
    cases: list[Case] = []
    dry: set[str] = set()
    for i, k in enumerate(kinds):
        n = max(1, round(args.cases * KINDS[k][1] / share))
        made = generate(k, n, args.seed * 1000 + i)
        print(f"generated {len(made):5d} {k} cases", file=sys.stderr, flush=True)
        cases += made
        if len(made) < n:  # a kind of finitely many cases (every option's values) ran dry
            dry.add(k)
    # what the dry kinds could not make, the others make (another seed), so that the run
    # holds the number of cases asked for
    rich = [k for k in kinds if k not in dry]
    for j, k in enumerate(rich):
        short = args.cases - len(cases)
        if short <= 0:
            break
        n = max(1, round(short * KINDS[k][1] / sum(KINDS[r][1] for r in rich[j:])))
        more = generate(k, n, args.seed * 1000 + 500 + j)
        print(f"generated {len(more):5d} more {k} cases", file=sys.stderr, flush=True)
        cases += more
    # warm the parent's imports once, so that every forked worker starts with them
    import microfab.cli  # noqa: F401

    print(
        f"running {len(cases)} cases on {args.workers} workers, {args.timeout:g} s of CPU "
        "each at most",
        file=sys.stderr,
        flush=True,
    )
    seen: Counter[str] = Counter()
    t_run = time.monotonic()

    def on_result(out: Outcome) -> None:
        seen[out.outcome] += 1
        n = sum(seen.values())
        if n % 500 == 0 or (out.failed and seen[out.outcome] <= 3):
            bad = ", ".join(f"{k} {v}" for k, v in sorted(seen.items()))
            print(f"  {n}/{len(cases)} ({bad})", file=sys.stderr, flush=True)

    results = run_pool(cases, workers=args.workers, timeout_s=args.timeout, on_result=on_result)
    wall = time.monotonic() - t0
    failed = [r for r in results if r.failed]
    groups: dict[tuple[str, str, str], list[Outcome]] = {}
    for r in failed:
        groups.setdefault((r.case.kind, r.outcome, _signature(r)), []).append(r)
    for (kind, outcome, sig), rs in list(groups.items())[: args.show]:
        r = rs[0]
        print(f"\n{outcome.upper()} x{len(rs)} [{kind}] {sig}\n  {r.case.describe()[:300]}")
        print("  " + (r.detail if args.tracebacks else r.detail.splitlines()[0])[:3000])
        if r.changed:
            print(f"  changed: {', '.join(r.changed)}")
    if len(groups) > args.show:
        print(f"\n... and {len(groups) - args.show} more kinds of failure")
    if args.save is not None and failed:
        for j, r in enumerate(failed):
            d = args.save / f"{j:04d}-{r.case.kind}-{r.outcome}"
            d.mkdir(parents=True, exist_ok=True)
            (d / "command.txt").write_text(r.case.describe() + "\n" + r.detail + "\n")
            for rel, content in r.case.files:
                (d / rel).parent.mkdir(parents=True, exist_ok=True)
                (d / rel).write_bytes(content)
    if args.accepted is not None:  # to review what was accepted: lenient or nonsense?
        lines = sorted(r.case.describe() for r in results if r.outcome == "accepted")
        args.accepted.write_text("\n".join(lines) + "\n", encoding="utf-8")
    slow = sorted(results, key=lambda r: r.seconds, reverse=True)[:3]
    if args.slow:
        for r in slow:
            print(f"slow {r.seconds:.1f} s {r.outcome}: {r.case.describe()[:300]}")
    print()
    print(format_table(results))
    print(
        f"\n{len(results)} cases in {wall:.0f} s ({time.monotonic() - t_run:.0f} s running, "
        f"{args.workers} workers, seed {args.seed}); slowest "
        + ", ".join(f"{r.seconds:.1f} s ({r.case.kind})" for r in slow)
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
