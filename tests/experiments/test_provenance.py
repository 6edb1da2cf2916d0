"""Every reproduction labels every row: input from the paper, fitted to it, or predicted.

The labels are derived (`microfab.machines.provenance`); these tests hold the reproductions
to them: every row has one, in the table and in ``--json``; no row labelled predicted is
compared with a number a calibration fits; and every number a calibration fits appears in
some reproduction's rows (a fitted number never sits unlabelled beside the seed's).
"""

from __future__ import annotations

from typing import Any

import pytest

from microfab.core.provenance import LABEL_COLUMN
from microfab.experiments.catalog import REPRODUCTIONS
from microfab.machines import provenance

#: Reproductions that run in seconds, with their quickest honest options. The others
#: (stage-models, reference-opt: trained networks; nanomanipulator, laser-micromachining)
#: are checked by their own packages' tests.
FAST: dict[str, dict[str, Any]] = {
    "msl-ilc": {"iterations": 3},
    "slm-shaper": {},
    "droplet-fig4": {"workers": 2},
}


def _quiet(*_: object) -> None:
    pass


@pytest.fixture(scope="module")
def results() -> dict[str, Any]:
    out = {}
    for name, opts in FAST.items():
        rep = REPRODUCTIONS[name]
        out[name] = rep.run(rep.parse_options(opts), _quiet)
    return out


def _held_targets() -> dict[str, str]:
    return {
        q: c.command for c in provenance.calibrations() if provenance.holds(c) for q in c.targets
    }


@pytest.mark.parametrize("name", list(FAST))
def test_every_row_has_a_label_in_the_table_and_the_json(
    results: dict[str, Any], name: str
) -> None:
    res = results[name]
    js = res.to_json()["provenance"]
    assert [t["table"] for t in js] == [t.title for t in res.tables]
    for table, entry in zip(res.tables, js, strict=True):
        assert table.columns[-1] == LABEL_COLUMN
        assert len(table.labels) == len(table.rows) == len(entry["rows"])
        for row in entry["rows"]:
            assert row["label"] in ("input", "fitted", "predicted", "mixed")


@pytest.mark.parametrize("name", list(FAST))
def test_no_row_labelled_predicted_is_a_calibration_target(
    results: dict[str, Any], name: str
) -> None:
    targets = _held_targets()
    # a number a calibration holds back (its checks) is predicted wherever a row shows it
    checks = {q for c in provenance.calibrations() for q in c.checks}
    for table in results[name].tables:
        for row, lab in zip(table.rows, table.labels, strict=True):
            held = sorted(set(lab.fitted) & checks)
            assert not held, f"{table.title}: {row[0]} shows {held} as fitted; it is a check"
            if lab.origin == "predicted":
                hit = [q for q in lab.quantities if q in targets]
                assert not hit, f"{table.title}: {row[0]} is labelled predicted but {hit} is fitted"
            if lab.origin in ("fitted", "mixed") and lab.fitted:
                assert set(lab.fitted) <= set(targets)


def test_every_target_of_these_calibrations_is_shown_and_labelled(results: dict[str, Any]) -> None:
    shown = {
        q: lab
        for res in results.values()
        for t in res.tables
        for lab in t.labels
        for q in lab.quantities
    }
    for cal in provenance.calibrations():
        if cal.command.startswith(("microfab calibrate galvo", "microfab droplet calibrate")):
            missing = sorted(cal.targets - set(shown))
            assert not missing, f"{cal.command}: no reproduction row shows {missing}"
            assert all(q in shown[q].fitted for q in cal.targets)


def test_a_table_without_labels_is_refused() -> None:
    from microfab.experiments.kinds import ReproductionResult
    from microfab.report.tables import Table

    with pytest.raises(ValueError, match="no row labels"):
        ReproductionResult(tables=(Table(title="t", columns=("a",), rows=[("1",)]),))
