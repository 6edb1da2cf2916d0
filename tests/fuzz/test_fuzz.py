"""A seeded subset of ``make fuzz`` in the normal suite: about 1000 generated inputs.

Each kind of input a user hands microfab (see `fuzz_cases`) runs through its command with
a fixed hypothesis seed (``derandomize``); every case must be accepted or refused cleanly:
exit code 2 with exactly one ``error:`` line and every file in the folder left as it was.
An uncaught exception, a hang, a multi-line refusal or a refusal that changed a file fails
the test, and hypothesis shrinks the input to a small example.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import pytest
from fuzz_cases import KINDS
from fuzz_driver import Case, run_case
from fuzz_options import cases_of, missing_generators
from hypothesis import HealthCheck, given, settings

#: Cases per kind: 1000 in all, weighted to the cheap kinds (a drawing that is read is
#: also drawn, a third of a second each).
SUBSET = {
    "dxf": 88,
    "svg": 88,
    "dat": 40,
    "shape": 50,
    "traj": 30,
    "job": 130,
    "trial": 120,
    "droplet": 60,
    "frames": 50,
    # seed 003 part 2 (fuzz_slm): a run accepted costs 0.1 to 1 s, so a few each
    "identify-chirp": 15,
    "shaper-design": 15,
    "slm-scan-time": 15,
    # every option of every command (fuzz_options): a case accepted runs a cheap recipe
    "opt-number": 60,
    "opt-text": 30,
    "opt-flag": 10,
    "out-path": 40,
    "in-path": 40,
    "state": 10,
    "set": 40,
    "mode": 30,
    "special": 0,
    # two processes at once per writing command (fuzz_concurrency): ~10 s each, make fuzz
    "together": 0,
    # every declared bound (fuzz_options): all of them, in their own test below
    "opt-bound": 0,
    # a generator per file kind (fuzz_files, from microfab.io.filekinds): 0.1 s a case
    "file-trace": 12,
    "file-frf": 6,
    "file-ilc-state": 12,
    "file-rc-contour": 6,
    "file-frame-index": 8,
    "file-run-list": 8,
    "file-ann-model": 8,
    "file-tf-model": 8,
    "file-shaper": 8,
    "file-stage-model": 8,
    "file-optimize-summary": 8,
}


def _fuzz_test(kind: str) -> Callable[[], None]:
    @settings(
        max_examples=SUBSET[kind],
        derandomize=True,
        database=None,
        deadline=None,
        suppress_health_check=list(HealthCheck),
    )
    @given(KINDS[kind][0]())
    def test(case: Case) -> None:
        out = run_case(case)
        assert out.outcome in ("refused", "accepted"), (
            f"{out.outcome}: {case.describe()}\n{out.detail}\nchanged: {out.changed}"
        )

    name = kind.replace("-", "_")
    test.__name__ = test.__qualname__ = f"test_{name}_inputs_are_accepted_or_refused_cleanly"
    return test


test_dxf = _fuzz_test("dxf")
test_svg = _fuzz_test("svg")
test_dat = _fuzz_test("dat")
test_shape = _fuzz_test("shape")
test_traj = _fuzz_test("traj")
test_job = _fuzz_test("job")
test_trial = _fuzz_test("trial")
test_droplet = _fuzz_test("droplet")
test_frames = _fuzz_test("frames")
test_identify_chirp = _fuzz_test("identify-chirp")
test_shaper_design = _fuzz_test("shaper-design")
test_slm_scan_time = _fuzz_test("slm-scan-time")
test_opt_number = _fuzz_test("opt-number")
test_opt_text = _fuzz_test("opt-text")
test_opt_flag = _fuzz_test("opt-flag")
test_out_path = _fuzz_test("out-path")
test_in_path = _fuzz_test("in-path")
test_state = _fuzz_test("state")
test_set = _fuzz_test("set")
test_mode = _fuzz_test("mode")
test_file_trace = _fuzz_test("file-trace")
test_file_frf = _fuzz_test("file-frf")
test_file_optimize_summary = _fuzz_test("file-optimize-summary")
test_file_ilc_state = _fuzz_test("file-ilc-state")
test_file_rc_contour = _fuzz_test("file-rc-contour")
test_file_frame_index = _fuzz_test("file-frame-index")
test_file_run_list = _fuzz_test("file-run-list")
test_file_ann_model = _fuzz_test("file-ann-model")
test_file_tf_model = _fuzz_test("file-tf-model")
test_file_shaper = _fuzz_test("file-shaper")
test_file_stage_model = _fuzz_test("file-stage-model")


def test_every_writing_command_has_a_together_case() -> None:
    from fuzz_concurrency import together_cases
    from fuzz_workspace import RECIPES

    writing = {name for name, r in RECIPES.items() if r.outputs}
    assert {c.note.split(":")[0] for c in together_cases()} == writing


@pytest.mark.parametrize("command", ["ilc step", "stage excite"])
def test_two_at_once_leave_a_usable_folder(command: str) -> None:
    """Two of a command released at once on one folder (``make fuzz`` runs them all)."""
    from fuzz_concurrency import together_cases

    case = next(c for c in together_cases() if c.note.startswith(f"{command}:"))
    out = run_case(case)
    assert out.outcome in ("accepted", "refused"), f"{out.outcome}: {out.detail}"


def test_every_special_file_is_refused_unopened() -> None:
    """Every path of every command as a FIFO or a symbolic-link loop: refused on one
    line, nothing changed (a FIFO opened would hang the case)."""
    cases = cases_of("special")
    assert len(cases) >= 100
    bad = []
    for case in cases:
        out = run_case(case, timeout_s=10.0)
        if out.outcome != "refused":
            bad.append(f"{out.outcome}: {case.describe()} {out.detail[:200]}")
    assert not bad, "\n".join(bad)


def test_every_declared_bound_is_enforced() -> None:
    """Each number just outside its declared range (`microfab.cli._options`) is refused
    on one line with every file as it was, for every option of every command."""
    cases = cases_of("opt-bound")
    assert len(cases) >= 100  # two bounds of most of the ~115 numbers
    bad = []
    for case in cases:
        out = run_case(case)
        if out.outcome != "refused":
            bad.append(f"{out.outcome}: {case.describe()} {out.detail[:200]}")
    assert not bad, "\n".join(bad)


def test_the_subset_covers_every_kind_with_about_1000_cases() -> None:
    assert set(SUBSET) == set(KINDS)
    assert 900 <= sum(SUBSET.values()) <= 1100


def test_every_option_of_every_command_has_a_generator() -> None:
    """A new command, or a path option nobody told the generator about, fails here."""
    assert missing_generators() == []


def test_the_option_kinds_attack_every_command() -> None:
    from fuzz_options import OPTION_KINDS, commands

    attacked = {c.note.split(":")[0] for kind in OPTION_KINDS for c in cases_of(kind)}
    attacked |= {"reproduce"} if cases_of("set") else set()
    assert set(commands()) <= attacked
