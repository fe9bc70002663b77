"""The experimenter's printable sheet of a schedule (``roughsense protocol --sheet``): HTML or Markdown.

Rendering only: the schedule itself is drawn by :func:`roughsense.analysis.magnitude_estimation.make_schedule`, and a filled-in
Markdown sheet is read back by :func:`roughsense.io.ratings_file.read_ratings`. The gratings a rig should add to tell
period from groove width are chosen by the command (cli/ratings_protocol.py); :func:`groove_advice` words them, for
the console and the sheet alike.
"""
from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from ..errors import ConfigError, InputError
from ..io.csv_read import csv_line
from ..paper import REFERENCE_SPECIMEN

_HTML_SHEET = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{{ title }}</title>
<style>
  body { font-family: system-ui, sans-serif; margin: 1.5cm; }
  section { break-after: page; page-break-after: always; }
  section:last-child { break-after: auto; page-break-after: auto; }
  table { border-collapse: collapse; width: 100%; margin-top: 0.5em; }
  th, td { border: 1px solid #444; padding: 0.45em 0.6em; text-align: left; }
  td.rating { width: 35%; }
  td.line, th.line { color: #777; font-size: 0.8em; width: 4em; }
  .note { font-size: 0.9em; color: #333; }
</style>
</head>
<body>
{% if advice %}
<aside class="note">
{% for paragraph in advice %}
  <p>{{ paragraph }}</p>
{% endfor %}
</aside>
{% endif %}
{% for block in blocks %}
<section>
  <h1>{{ title }}</h1>
  <h2>Participant {{ block.participant }} &middot; session {{ block.session }}</h2>
  <p class="note">Reference <strong>{{ reference }}</strong> = 1.0 (may be touched at any time; not rated).
  Press only &mdash; no sliding. Vision blocked. Rate how many times rougher than the reference each specimen feels
  (any positive number). Type the ratings into the <code>rating</code> column of {{ csv_name }} at the line shown.</p>
  <p class="note">Date: ____________ &nbsp; Experimenter: ____________</p>
  <table>
    <thead><tr><th class="line">line</th><th>order</th><th>specimen</th><th>rating</th></tr></thead>
    <tbody>
    {% for row in block.rows %}
      <tr><td class="line">{{ row.line }}</td><td>{{ row.order }}</td><td>{{ row.specimen }}</td><td class="rating"></td></tr>
    {% endfor %}
    </tbody>
  </table>
</section>
{% endfor %}
</body>
</html>
"""


def groove_advice(specs: Sequence[str]) -> list[str]:
    """Which gratings to print besides the set, and why, in two paragraphs (none where there is nothing to add).

    The why: a set whose rectangles share one land/groove geometry (the paper's: half land, half groove) ties the
    groove width to the period, and people feel the groove."""
    if not specs:
        return []
    return [
        f"Print these gratings too, to tell period from groove width: {', '.join(specs)} (rect:PERIOD:DEPTH:LAND in "
        "mm: at each period a land of 0.3 and of 0.7 of it, so the groove is the rest; 1 mm deep like the paper's).",
        "Why: where every rectangle of a set has one land/groove geometry (the paper's are all half land, half "
        "groove), its period stands in for its groove width, and a model fitted on them learns the period. People "
        "feel the groove: roughness grows with groove width and falls a little with land width (Lederman 1974, "
        "Perception & Psychophysics 16:385), and groove width alone predicts most of it (Klatzky & Lederman 2007). "
        "Gratings whose land differs at the same period set the two apart. Give every rectangle's ridge_width_mm "
        "and groove_width_mm in specimens.csv: the study report holds out each land/groove geometry from them. The "
        "digital twin runs such a set: roughsense study --study builtin:paper+grooves.",
    ]


def _blocks(schedule: pd.DataFrame) -> list[dict]:
    missing = [c for c in ("participant", "session", "order", "specimen") if c not in schedule.columns]
    if missing:
        raise InputError(f"schedule lacks column(s) {', '.join(missing)}")
    blocks: list[dict] = []
    for position, row in enumerate(schedule.itertuples(index=False)):
        key = (str(row.participant), str(row.session))
        if not blocks or (blocks[-1]["participant"], blocks[-1]["session"]) != key:
            blocks.append({"participant": key[0], "session": key[1], "rows": []})
        blocks[-1]["rows"].append({"line": csv_line(position), "order": int(row.order), "specimen": str(row.specimen)})
    return blocks


def render_sheet(
    schedule: pd.DataFrame,
    fmt: str = "html",
    *,
    reference: str = REFERENCE_SPECIMEN,
    title: str = "Magnitude estimation of roughness",
    csv_name: str = "the schedule CSV",
    advice: Sequence[str] = (),
) -> str:
    """A printable sheet for the experimenter, one page per participant x session, rows in CSV order.

    ``"html"`` prints well from a browser (with the schedule CSV line of each trial for typing the
    ratings in); ``"markdown"`` is a plain-text sheet whose tables carry the rating columns, so the
    filled-in Markdown file itself can be read back by :func:`roughsense.io.ratings_file.read_ratings`.
    ``advice`` (:func:`groove_advice`) opens the sheet, before the first participant's page.
    """
    blocks = _blocks(schedule)
    if fmt == "html":
        import jinja2

        template = jinja2.Environment(autoescape=True, trim_blocks=True, lstrip_blocks=True).from_string(_HTML_SHEET)
        return template.render(title=title, reference=reference, blocks=blocks, csv_name=csv_name, advice=advice)
    if fmt not in ("markdown", "md"):
        raise ConfigError(f"sheet format must be html or markdown, got {fmt!r}")

    def cell(value: object) -> str:
        text = str(value)
        if "|" in text or "\n" in text:
            raise ConfigError(f"cannot put {text!r} in a Markdown table cell")
        return text

    out = [f"# {title}", "",
           f"Reference **{cell(reference)}** = 1.0 (may be touched at any time; not rated). Press only, no sliding; "
           "vision blocked. Write how many times rougher than the reference each specimen feels (any positive number) "
           "in the `rating` column. Leave a cell empty for a trial that did not happen.", ""]
    for paragraph in advice:
        out += [cell(paragraph), ""]
    for block in blocks:
        out += [f"## Participant {cell(block['participant'])}, session {cell(block['session'])}", "",
                "| participant | session | order | specimen | rating |", "|---|---|---|---|---|"]
        out += [f"| {cell(block['participant'])} | {cell(block['session'])} | {r['order']} | {cell(r['specimen'])} |  |"
                for r in block["rows"]]
        out.append("")
    return "\n".join(out)
