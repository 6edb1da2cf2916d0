"""Tables of numbers for reports and the terminal: ours beside the seed's.

A `Table` is plain data (title, column heads, rows of cells already formatted as text), so
the same table is printed by the CLI and written into ``report.html``.
"""

from __future__ import annotations

import html
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from microfab.core.provenance import LABEL_COLUMN, RowLabel

__all__ = ["DASH", "Table", "ratio", "versus"]

#: What a cell shows where there is no value.
DASH = "—"


def versus(
    ours: float | None, seed: float | None, fmt: Callable[[float], str] = "{:.3g}".format
) -> str:
    """One cell ``"ours / seed"``; a dash stands for a missing value.

    Examples
    --------
    >>> versus(4.2, 4.11, "{:.2f}".format)
    '4.20 / 4.11'
    >>> versus(1.0, None)
    '1 / —'
    """
    a = DASH if ours is None else fmt(float(ours))
    b = DASH if seed is None else fmt(float(seed))
    return f"{a} / {b}"


def ratio(ours: float | None, seed: float | None) -> str:
    """``ours / seed`` as a number with two decimals, a dash when undefined.

    Examples
    --------
    >>> ratio(5.0, 4.0)
    '1.25'
    >>> ratio(5.0, 0.0)
    '—'
    """
    if ours is None or seed is None or seed == 0:
        return DASH
    return f"{float(ours) / float(seed):.2f}"


@dataclass(frozen=True, kw_only=True)
class Table:
    """A titled table of text cells.

    Parameters
    ----------
    title : str
        Caption (units in it, e.g. ``"... [mV]"``).
    columns : sequence of str
        Column heads.
    rows : sequence of sequence of str
        Rows, each as long as ``columns``.
    note : str
        A line under the table (e.g. where the seed's numbers come from).
    labels : sequence of RowLabel
        Where each row's numbers come from (`microfab.core.provenance`); when given, one
        per row, and the last column is `LABEL_COLUMN` holding each label's text.
    """

    title: str
    columns: Sequence[str]
    rows: Sequence[Sequence[str]]
    note: str = ""
    labels: Sequence[RowLabel] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "columns", tuple(self.columns))
        object.__setattr__(self, "rows", tuple(tuple(r) for r in self.rows))
        object.__setattr__(self, "labels", tuple(self.labels))
        for i, row in enumerate(self.rows):
            if len(row) != len(self.columns):
                raise ValueError(
                    f"table {self.title!r}: row {i} has {len(row)} cells, "
                    f"expected {len(self.columns)}"
                )
        if self.labels:
            if len(self.labels) != len(self.rows) or self.columns[-1] != LABEL_COLUMN:
                raise ValueError(
                    f"table {self.title!r}: labels need one per row and a last column "
                    f"{LABEL_COLUMN!r}"
                )
            for i, (row, lab) in enumerate(zip(self.rows, self.labels, strict=True)):
                if row[-1] != lab.text:
                    raise ValueError(f"table {self.title!r}: row {i}'s label cell is not its label")

    def with_labels(self, labels: Sequence[RowLabel]) -> Table:
        """A copy with a `LABEL_COLUMN` column holding ``labels`` (one per row)."""
        if self.labels:
            raise ValueError(f"table {self.title!r} is labelled already")
        if len(labels) != len(self.rows):
            raise ValueError(
                f"table {self.title!r}: {len(labels)} labels for {len(self.rows)} rows"
            )
        return Table(
            title=self.title,
            columns=(*self.columns, LABEL_COLUMN),
            rows=[(*r, lab.text) for r, lab in zip(self.rows, labels, strict=True)],
            note=self.note,
            labels=labels,
        )

    def labels_json(self) -> list[dict[str, object]]:
        """Per row: its cells without the label, and the label (`RowLabel.to_json`)."""
        return [
            {"row": list(r[:-1]), **lab.to_json()}
            for r, lab in zip(self.rows, self.labels, strict=True)
        ]

    def to_html(self) -> str:
        """The table as an HTML ``<table>`` (numbers right-aligned)."""
        head = "".join(f"<th>{html.escape(c)}</th>" for c in self.columns)
        body = []
        for row in self.rows:
            cells = "".join(
                f'<td class="num">{html.escape(c)}</td>' if i else f"<td>{html.escape(c)}</td>"
                for i, c in enumerate(row)
            )
            body.append(f"<tr>{cells}</tr>")
        note = f'<p class="muted">{html.escape(self.note)}</p>' if self.note else ""
        return (
            f"<table><caption>{html.escape(self.title)}</caption>"
            f"<thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>{note}"
        )

    def to_text(self) -> str:
        """Plain text: the title, then one tab-separated line per row (never wrapped)."""
        lines = [self.title, "\t".join(self.columns)]
        lines += ["\t".join(r) for r in self.rows]
        if self.note:
            lines.append(self.note)
        return "\n".join(lines)
