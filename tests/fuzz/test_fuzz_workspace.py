"""`fuzz_workspace`: a recipe for every command, and each recipe a valid run."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

import fuzz_workspace
from fuzz_workspace import RECIPES, SLOW


def _leaf_commands() -> set[str]:
    import typer.main

    from microfab.cli import app

    out: set[str] = set()

    def walk(cmd: object, path: list[str]) -> None:
        subs = getattr(cmd, "commands", None)
        if subs is None:
            out.add(" ".join(path))
            return
        for name, sub in subs.items():
            walk(sub, [*path, name])

    walk(typer.main.get_command(app), [])
    return out


def test_every_leaf_command_has_a_recipe_and_no_other() -> None:
    leaves = _leaf_commands()
    assert set(RECIPES) == leaves, (
        f"no recipe: {sorted(leaves - set(RECIPES))}; not a command: "
        f"{sorted(set(RECIPES) - leaves)}"
    )
    assert set(SLOW) <= set(RECIPES)
    for name, r in RECIPES.items():
        assert r.argv[: len(name.split())] == tuple(name.split()), name
        for p in (*r.inputs, *r.outputs):
            assert not Path(p).is_absolute() and ".." not in Path(p).parts, (name, p)


def test_the_workspace_holds_every_input_and_is_small(tmp_path: Path) -> None:
    fuzz_workspace.build_workspace(tmp_path)
    for name, r in RECIPES.items():
        for p in r.inputs:
            assert (tmp_path / p).exists(), (name, p)
        for p in r.outputs:
            if p not in r.inputs:
                assert not (tmp_path / p).exists(), (name, p)
    size = sum(p.stat().st_size for p in tmp_path.rglob("*") if p.is_file())
    assert size < 5_000_000


@pytest.mark.parametrize("name", sorted(set(RECIPES) - set(SLOW)))
def test_recipe_runs_and_exits_0(name: str) -> None:
    outcome, _seconds, detail = fuzz_workspace.run_recipe(name)
    assert outcome == "accepted", f"{name}: {outcome}: {detail}"
