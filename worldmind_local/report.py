"""Plain-text results table in the paper's shape: one row per method/model, SR and GC per subset + Avg."""

from __future__ import annotations

from typing import Any

__all__ = ["format_results"]


def _cell(v: Any) -> str:
    return "-" if v is None else f"{v:.1f}"


def _gain(v: Any) -> str:
    """A seeded row's difference from its from-scratch row, signed ("-" when there is none)."""
    return "-" if v is None else f"{v:+.1f}"


def env_line(env: str | None) -> str:
    """Say where the numbers come from: the symbolic twin is not the real simulator."""
    where = {"twin": "symbolic twin (not the real simulator)", "embodiedbench": "real simulator (EmbodiedBench)"}
    return f"SR and GC in percent; env: {where.get(env or '', env or 'unknown')}"


def format_results(results: dict[str, Any], env: str | None = None) -> str:
    """The plain-text table `worldmind run` prints (percents), headed by the env the numbers come from.
    `worldmind report` builds the paper's tables, statistics and figures from run folders."""
    lines: list[str] = [env_line(env or results.get("env"))]
    for bench in sorted({row["benchmark"] for row in results.get("table", [])}):
        rows = [r for r in results["table"] if r["benchmark"] == bench]
        subsets: list[str] = []
        for r in rows:
            subsets += [s for s in r["subsets"] if s not in subsets]
        seeded = any(r.get("memory_from") for r in rows)
        head = ["method", "planner", "seed"] + (["memory_from"] if seeded else []) + \
               [f"SR:{s}" for s in subsets] + ["SR:avg"] + [f"GC:{s}" for s in subsets] + ["GC:avg"] + \
               (["dSR:avg", "dGC:avg"] if seeded else []) + ["n"]
        body = []
        for r in rows:
            opts = r.get("options") or {}
            flags = [k for k in ("goal_experience", "process_experience", "verifier") if opts.get(k) is False]
            method = r["method"] + "".join(f" -{f.split('_')[0]}" for f in flags)
            if r.get("memory_budget") is not None:
                method += f" Mem{r['memory_budget']}"
            if r.get("perturb"):
                method += f" {r['perturb']}"
            if r.get("task_order_seed") is not None:
                method += f" order{r['task_order_seed']}"
            n = sum(v["episodes"] for v in r["subsets"].values())
            gain = r.get("gain") or {}
            body.append(
                [method, r["planner"].split(":", 1)[-1], str(r.get("seed"))]
                + ([r.get("memory_from") or "-"] if seeded else [])
                + [_cell(r["subsets"].get(s, {}).get("SR")) for s in subsets] + [_cell(r["avg"]["SR"])]
                + [_cell(r["subsets"].get(s, {}).get("GC")) for s in subsets] + [_cell(r["avg"]["GC"])]
                + ([_gain(gain.get("SR")), _gain(gain.get("GC"))] if seeded else []) + [str(n)]
            )
        widths = [max(len(x) for x in col) for col in zip(head, *body, strict=False)]
        lines.append(f"== {bench} ==")
        lines.append("  ".join(h.ljust(w) for h, w in zip(head, widths, strict=False)))
        lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths, strict=False)) for row in body]
    failed = [s for s in results.get("streams", []) if s.get("status") != "finished"]
    if failed:
        lines.append("failed streams:")
        lines += [f"  {s['stream_id']}: {s.get('error')}" for s in failed]
    return "\n".join(lines)
