"""Tables as Markdown, LaTeX (booktabs, the paper's style), CSV (raw numbers) and HTML fragments."""

from __future__ import annotations

import csv
import html
import io
from typing import Any

from worldmind_local.reporting.model import Num, Table

__all__ = ["to_markdown", "to_latex", "to_csv", "to_html", "cell_text"]


def cell_text(cell: Any, pm: str = "±") -> str:
    if cell is None:
        return "-"
    if isinstance(cell, Num):
        return cell.text(pm)
    return str(cell)


def to_markdown(table: Table) -> str:
    def esc(text: str) -> str:
        return text.replace("|", "\\|")

    lines = [f"### {table.title}", ""]
    if table.caption:
        lines += [f"*{table.caption}*", ""]
    lines.append("| " + " | ".join(esc(c) for c in table.columns) + " |")
    lines.append("|" + "|".join("---" for _ in table.columns) + "|")
    for row in table.rows:
        lines.append("| " + " | ".join(esc(cell_text(c)) for c in row) + " |")
    if not table.rows:
        lines.append("| " + " | ".join("" for _ in table.columns) + " |")
    lines += [""] + [f"> {n}" for n in table.notes]
    return "\n".join(lines).rstrip() + "\n"


_LATEX_SPECIAL = {"&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_", "{": r"\{", "}": r"\}",
                  "~": r"\textasciitilde{}", "^": r"\textasciicircum{}", "\\": r"\textbackslash{}",
                  "±": r"$\pm$", "✓": r"\checkmark", "∞": r"$\infty$", "Δ": r"$\Delta$", "→": r"$\to$"}


def _tex(text: str) -> str:
    return "".join(_LATEX_SPECIAL.get(ch, ch) for ch in text)


def to_latex(table: Table) -> str:
    spec = "l" * min(3, len(table.columns)) + "c" * max(0, len(table.columns) - 3)
    out = [r"\begin{table*}[t]", r"\centering", r"\resizebox{\textwidth}{!}{%", rf"\begin{{tabular}}{{{spec}}}",
           r"\toprule"]
    if table.header_groups and any(name for name, _ in table.header_groups):
        cells, start, rules = [], 1, []
        for name, span in table.header_groups:
            if not name:
                cells.append(" & ".join([""] * span))
            elif span == 1:
                cells.append(rf"\textbf{{{_tex(name)}}}")
            else:
                cells.append(rf"\multicolumn{{{span}}}{{c}}{{\textbf{{{_tex(name)}}}}}")
            if name:
                rules.append(rf"\cmidrule(lr){{{start}-{start + span - 1}}}")
            start += span
        out.append(" & ".join(cells) + r" \\")
        out.append(" ".join(rules))
    out.append(" & ".join(rf"\textbf{{{_tex(c)}}}" for c in table.columns) + r" \\")
    out.append(r"\midrule")
    for row in table.rows:
        out.append(" & ".join(_tex(cell_text(c)) for c in row) + r" \\")
    out += [r"\bottomrule", r"\end{tabular}", "}"]
    caption = table.caption + (" " + " ".join(table.notes) if table.notes else "")
    out += [rf"\caption{{{_tex(caption)}}}", rf"\label{{tab:{_tex(table.key)}}}", r"\end{table*}"]
    return "\n".join(out) + "\n"


def to_csv(table: Table) -> str:
    """One row per table row; a number cell becomes its value plus _sd, _lo, _hi, _n, _p columns (only
    those the column uses), so the file is numbers, not formatted text."""
    extras: dict[int, list[str]] = {}
    for j in range(len(table.columns)):
        used = []
        for part in ("sd", "lo", "hi", "n", "p"):
            if any(isinstance(r[j], Num) and getattr(r[j], part) is not None for r in table.rows if j < len(r)):
                used.append(part)
        extras[j] = used
    header = []
    for j, col in enumerate(table.columns):
        header.append(col)
        header += [f"{col}_{p}" for p in extras[j]]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    for row in table.rows:
        out: list[Any] = []
        for j, cell in enumerate(row):
            if isinstance(cell, Num):
                out.append("" if cell.value is None else cell.value)
                out += ["" if getattr(cell, p) is None else getattr(cell, p) for p in extras[j]]
            else:
                out.append("" if cell is None else cell)
                out += [""] * len(extras[j])
        writer.writerow(out)
    return buf.getvalue()


def to_html(table: Table) -> str:
    """A <table> with its caption, for the static site (numbers right-aligned, CIs in smaller type)."""
    e = html.escape
    parts = [f'<section class="table" id="{e(table.key)}"><h3>{e(table.title)}</h3>']
    if table.caption:
        parts.append(f'<p class="caption">{e(table.caption)}</p>')
    parts.append("<div class=\"scroll\"><table><thead>")
    if table.header_groups and any(name for name, _ in table.header_groups):
        parts.append("<tr>" + "".join(f'<th colspan="{span}">{e(name)}</th>' for name, span in table.header_groups)
                     + "</tr>")
    parts.append("<tr>" + "".join(f"<th>{e(c)}</th>" for c in table.columns) + "</tr></thead><tbody>")
    for row in table.rows:
        tds = []
        for cell in row:
            cls = ' class="num"' if isinstance(cell, (Num, int, float)) and not isinstance(cell, bool) else ""
            tds.append(f"<td{cls}>{e(cell_text(cell))}</td>")
        parts.append("<tr>" + "".join(tds) + "</tr>")
    parts.append("</tbody></table></div>")
    parts += [f'<p class="note">{e(n)}</p>' for n in table.notes]
    parts.append("</section>")
    return "\n".join(parts)
