"""Comparison tables with each row's label: input from the paper, fitted to it, predicted.

The labels come from `microfab.machines.provenance.label` (the twins' data files and the
calibrations' targets); a table builder says only what each row shows (`Shows`). Labelling
reads no result: the same table gets the same column in ``microfab reproduce``, its
``--json`` and a job's report page.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence

from microfab.core.provenance import Shows
from microfab.machines.provenance import labels
from microfab.report.tables import Table

__all__ = ["OURS", "labelled"]

#: A row of our numbers compared with nothing the seed publishes (predicted).
OURS = Shows()


def labelled(
    table: Table,
    shows: Sequence[Shows] | Shows,
    *,
    not_applied: Collection[str] = (),
) -> Table:
    """``table`` with its `LABEL_COLUMN` column.

    Parameters
    ----------
    table : Table
        Unlabelled table.
    shows : Shows or sequence of Shows
        What each row shows (one per row), or one for every row.
    not_applied : collection of str
        Calibrations (their commands) this run did not use: their targets are predicted.
    """
    rows = [shows] * len(table.rows) if isinstance(shows, Shows) else list(shows)
    return table.with_labels(labels(rows, not_applied=not_applied))
