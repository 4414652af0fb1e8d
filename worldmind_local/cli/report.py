"""`worldmind report RUN [RUN ...]`: the paper's tables (md, LaTeX, CSV), figures and the episode viewer."""

from __future__ import annotations

import argparse
import sys
from typing import Any


def register(sub: Any) -> None:
    p = sub.add_parser(
        "report", help="tables, figures and a static episode viewer from run folders",
        description=("Builds, from any set of run folders, the paper's tables: main results (seeds as mean ± sd), "
                     "ablations, memory budget, transfer, robustness (rename, poisoning, task order), error "
                     "taxonomy, overhead, paired comparisons and per-stream intervals. Without --out prints "
                     "Markdown; with --out writes each --format plus figures (PNG and SVG)."),
    )
    p.add_argument("runs", nargs="+", metavar="RUN", help="run folders (a stream found in several: the first wins)")
    p.add_argument("--format", default="md", metavar="md,latex,csv,html",
                   help="comma list of md, latex, csv, html, or all (default md)")
    p.add_argument("--out", default=None, metavar="DIR", help="write the report here (default: Markdown to stdout)")
    p.add_argument("--reference", default=None, metavar="METHOD",
                   help="the method others are compared against (default worldmind)")
    p.add_argument("--no-figures", action="store_true", help="skip the figures (md/latex/csv only)")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from worldmind_local.reporting import FORMATS, write_report

    formats = list(FORMATS) if args.format.strip() == "all" else [f.strip() for f in args.format.split(",") if f.strip()]
    if args.out is None and formats != ["md"]:
        print("worldmind report: --format other than md needs --out DIR", file=sys.stderr)
        return 2
    result = write_report(args.runs, formats=formats, out=args.out, reference=args.reference,
                          figures=not args.no_figures)
    if args.out is None:
        print(result["markdown"])
        return 0
    print(f"worldmind report: {len(result['tables'])} table(s), {len(result.get('figures') or [])} figure(s) "
          f"-> {args.out}", file=sys.stderr)
    if "html" in formats:
        print(f"viewer: open {args.out}/site/index.html", file=sys.stderr)
    return 0
