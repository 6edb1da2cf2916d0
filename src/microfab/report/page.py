"""One self-contained HTML report page: title, notes, figures, tables.

Every job kind writes its report through `write_page`: its figures are rendered to PNG in
memory before anything is written, then the PNGs and ``report.html`` are written
atomically, so a failure while drawing leaves the folder as it was.
"""

from __future__ import annotations

import html
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from microfab.io.atomic import atomic_write_bytes, atomic_write_text
from microfab.report.tables import Table

__all__ = ["CSS", "Figure", "page_html", "write_page"]

CSS = """
body { font-family: -apple-system, "Segoe UI", Helvetica, Arial, sans-serif;
       max-width: 1100px; margin: 2em auto; padding: 0 1em; color: #222;
       line-height: 1.45; }
h1 { border-bottom: 2px solid #444; padding-bottom: .2em; }
h2 { margin-top: 2em; border-bottom: 1px solid #bbb; }
figure { margin: 1.5em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: .92em; color: #444; margin-top: .3em; }
table { border-collapse: collapse; margin: .8em 0 1.5em; font-size: .92em; }
th, td { border: 1px solid #bbb; padding: .25em .6em; }
th { background: #f0f0f0; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
caption { caption-side: top; text-align: left; font-weight: bold; padding: .3em 0; }
.muted { color: #666; }
"""


@dataclass(frozen=True, kw_only=True)
class Figure:
    """A rendered figure of a report.

    Attributes
    ----------
    name : str
        File name, e.g. ``"xy.png"``.
    png : bytes
        The rendered PNG.
    caption : str
        What it shows (and which seed figure it redraws).
    svg : bytes, optional
        The same figure as SVG, written beside the PNG (``<stem>.svg``) and linked.
    """

    name: str
    png: bytes
    caption: str
    svg: bytes | None = None

    @property
    def svg_name(self) -> str:
        """File name of the SVG version (``<stem>.svg``)."""
        return Path(self.name).with_suffix(".svg").name


def page_html(
    title: str,
    *,
    intro: str = "",
    notes: Sequence[str] = (),
    figures: Sequence[Figure] = (),
    tables: Sequence[Table] = (),
    sections: Sequence[str] = (),
) -> str:
    """The HTML text of a report page.

    Parameters
    ----------
    title : str
        Page title and heading.
    intro : str
        A paragraph under the heading (plain text).
    notes : sequence of str
        Bulleted notes (assumptions, what differs from the seed).
    figures : sequence of Figure
        Figures, referenced by file name.
    tables : sequence of Table
        Tables, after the figures.
    sections : sequence of str
        Extra HTML fragments appended at the end (already escaped).
    """
    body = [f"<h1>{html.escape(title)}</h1>"]
    if intro:
        body.append(f"<p>{html.escape(intro)}</p>")
    if notes:
        items = "".join(f"<li>{html.escape(str(n))}</li>" for n in notes)
        body.append(f"<h2>Notes</h2><ul>{items}</ul>")
    if figures:
        body.append("<h2>Figures</h2>")
        for fig in figures:
            cap = html.escape(fig.caption)
            vector = (
                f' <a href="{html.escape(fig.svg_name)}">(SVG)</a>' if fig.svg is not None else ""
            )
            body.append(
                f'<figure><img src="{html.escape(fig.name)}" alt="{cap}">'
                f"<figcaption>{cap}{vector}</figcaption></figure>"
            )
    if tables:
        body.append("<h2>Tables</h2>")
        body.extend(t.to_html() for t in tables)
    body.extend(sections)
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>{html.escape(title)}</title>\n<style>{CSS}</style>\n</head>\n<body>\n"
        + "\n".join(body)
        + "\n</body>\n</html>\n"
    )


def write_page(out_dir: str | os.PathLike[str], html_text: str, figures: Sequence[Figure]) -> Path:
    """Write the figures and ``report.html`` into ``out_dir``, each file atomically.

    Returns
    -------
    pathlib.Path
        Path of ``report.html``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for fig in figures:
        atomic_write_bytes(out / fig.name, fig.png)
        if fig.svg is not None:
            atomic_write_bytes(out / fig.svg_name, fig.svg)
    target = out / "report.html"
    atomic_write_text(target, html_text)
    return target
