"""Every table from synthetic runs whose numbers are chosen, checked against values computed here."""

from __future__ import annotations

import csv
import io
import statistics

import pytest

from worldmind_local.reporting import load_runs
from worldmind_local.reporting.build import build_tables, write_report
from worldmind_local.reporting.model import Num
from worldmind_local.reporting.render import to_csv, to_html, to_latex, to_markdown

P = "random:seeded-random"
S, F = (True, 1.0), (False, 0.0)
HALF = (False, 0.5)


def spec(subset="base", method="worldmind", seed=0, **kw):
    return {"benchmark": "eb_alfred", "subset": subset, "method": method, "planner": P, "seed": seed, **kw}


OUT = {  # (method, seed, subset) -> outcomes
    ("worldmind", 0, "base"): [S, S, F, HALF], ("worldmind", 0, "common_sense"): [S, F, F, F],
    ("worldmind", 1, "base"): [S, S, S, HALF], ("worldmind", 1, "common_sense"): [S, S, F, F],
    ("react", 0, "base"): [S, F, F, F], ("react", 0, "common_sense"): [F, F, F, HALF],
    ("react", 1, "base"): [F, F, F, F], ("react", 1, "common_sense"): [S, F, F, F],
}


def _sr(outcomes):
    return 100 * sum(s for s, _ in outcomes) / len(outcomes)


def _gc(outcomes):
    return 100 * sum(p for _, p in outcomes) / len(outcomes)


@pytest.fixture()
def tables(make_run):
    a = make_run("runA", [{"spec": spec(sub, m, 0), "outcomes": OUT[(m, 0, sub)]}
                          for m in ("worldmind", "react") for sub in ("base", "common_sense")])
    b = make_run("runB", [{"spec": spec(sub, m, 1), "outcomes": OUT[(m, 1, sub)]}
                          for m in ("worldmind", "react") for sub in ("base", "common_sense")])
    source = a / "streams" / "eb_alfred.common_sense.worldmind.seeded-random.s0" / "memory"
    c = make_run("runC", [
        {"spec": spec("base", memory_from=str(source)), "outcomes": [S, S, S, S]},
        {"spec": spec("base", perturb="rename"), "outcomes": [S, F, F, F]},
        {"spec": spec("base", method="react", perturb="rename"), "outcomes": [F, F, F, F]},
        {"spec": spec("base", task_order_seed=1), "outcomes": [S, F, S, F]},
        {"spec": spec("base", task_order_seed=2), "outcomes": [S, S, S, F]},
        {"spec": spec("base", memory_budget=0, options={"top_k": 2}), "outcomes": [F, F, F, F]},
        {"spec": spec("base", memory_budget=10, options={"top_k": 2}), "outcomes": [S, F, F, F]},
        {"spec": spec("base", memory_budget=10, options={"top_k": 3}), "outcomes": [S, S, F, F]},
        {"spec": spec("base", method="worldmind_goal_only"), "outcomes": [S, F, F, F]},
        {"spec": spec("base", method="naivemem"), "outcomes": [F, F, F, HALF]},
    ])
    runs = load_runs([a, b, c])
    return {t.key: t for t in build_tables([s for r in runs for s in r.streams])}, (a, b, c)


def _row(table, **match):
    idx = {c: i for i, c in enumerate(table.columns)}
    rows = [r for r in table.rows if all(r[idx[k]] == v for k, v in match.items())]
    assert len(rows) == 1, (match, [r[:4] for r in table.rows])
    return {c: rows[0][i] for c, i in idx.items()}


def test_main_table_mean_sd_over_seeds(tables) -> None:
    t = tables[0]["main_eb_alfred"]
    row = _row(t, Method="worldmind")
    for metric, fn in (("SR", _sr), ("GC", _gc)):
        per_seed_base = [fn(OUT[("worldmind", s, "base")]) for s in (0, 1)]
        cell = row[f"{metric} Base"]
        assert cell.value == pytest.approx(statistics.mean(per_seed_base))
        assert cell.sd == pytest.approx(statistics.stdev(per_seed_base), abs=0.01) and cell.n == 2
        avgs = [statistics.mean(fn(OUT[("worldmind", s, sub)]) for sub in ("base", "common_sense")) for s in (0, 1)]
        assert row[f"{metric} Avg"].value == pytest.approx(statistics.mean(avgs))
        assert row[f"{metric} Avg"].sd == pytest.approx(statistics.stdev(avgs), abs=0.01)
    assert row["Seeds"] == 2 and row["Episodes"] == 16 and row["Memory Scope"] == "Global"
    assert _row(t, Method="react")["Memory Scope"] == "Episodic"
    assert {r[1] for r in t.rows} == {"worldmind", "react", "worldmind_goal_only", "naivemem"}  # clean streams only
    assert "symbolic twin" in t.caption and "seeded-random" in t.caption


def test_ablation_controlled_budget_taxonomy_overhead(tables) -> None:
    t = tables[0]
    abl = t["ablation"]
    assert [r[1:3] for r in abl.rows] == [["✓", "-"], ["✓", "✓"]]
    full = abl.rows[1]
    assert full[3].value == pytest.approx(statistics.mean(
        [statistics.mean(_sr(OUT[("worldmind", s, sub)]) for sub in ("base", "common_sense")) for s in (0, 1)]))
    ctrl = t["controlled_ablation"]
    assert _row(ctrl, Variant="NaiveMem (control)")["Mean GC"].value == pytest.approx(12.5)
    budget = t["memory_budget_eb_alfred_seeded-random_worldmind"]
    labels = [r[0] for r in budget.rows]
    assert labels == ["Mem0 (top-2)", "Mem10 (top-2)", "Mem∞ (top-2)", "Mem10 (top-3)"]  # ∞: the clean streams
    assert _row(budget, **{"Memory Setting": "Mem10 (top-3)"})["SR Base"].value == 50.0
    tax = _row(t["taxonomy"], Method="react")
    outcomes = [o for k, v in OUT.items() if k[0] == "react" for o in v]
    assert tax["Success"] == sum(s for s, _ in outcomes) and tax["Episodes"] == 16
    assert tax["Step limit"] == 16 - tax["Success"]
    over = t["overhead"]
    row = _row(over, Method="worldmind", Metric="Process Exp. (tokens/reflection)")
    assert row["Base"].value == 40.0          # (30 + 10) reflector tokens per reflection
    assert _row(over, Method="worldmind", Metric="Retrieval time (seconds/step)")["Base"].value == 0.001


def test_transfer_robustness_task_order_and_comparisons(tables) -> None:
    t = tables[0]
    tr = t["transfer"]
    (row,) = tr.rows
    assert row[0] == "eb_alfred:seeded-random"      # the source stream's benchmark and planner, from the path
    assert row[3].value == 100.0 and row[4].value == pytest.approx(_sr(OUT[("worldmind", 0, "base")]))
    assert row[5].value == pytest.approx(100.0 - _sr(OUT[("worldmind", 0, "base")]))
    rob = t["robustness"]
    renamed = _row(rob, Method="worldmind", Perturbation="object rename (synonyms)")
    assert renamed["Pairs"] == 4                    # paired with the seed-0 clean stream, episode by episode
    assert renamed["ΔSR [95%]"].value == pytest.approx(_sr([S, F, F, F]) - _sr(OUT[("worldmind", 0, "base")]))
    assert _row(rob, Method="worldmind", Perturbation="clean")["SR"].value == pytest.approx(
        _sr(OUT[("worldmind", 0, "base")]))
    order = t["task_order"]
    gc_row = _row(order, Metric="GC")
    assert gc_row["Order seed 1"].value == 50.0 and gc_row["Order seed 2"].value == 75.0
    assert gc_row["Mean ± SD"].value == 62.5 and gc_row["Mean ± SD"].sd == pytest.approx(17.68, abs=0.01)
    assert gc_row["Original order"].value == pytest.approx(_gc(OUT[("worldmind", 0, "base")]))
    cmp = _row(t["comparisons"], A="worldmind", B="react")
    assert cmp["Pairs"] == 16
    wm = [o for k, v in OUT.items() if k[0] == "worldmind" for o in v]
    re_ = [o for k, v in OUT.items() if k[0] == "react" for o in v]
    assert cmp["ΔSR [95%]"].value == pytest.approx(_sr(wm) - _sr(re_))


def test_renderers(tables) -> None:
    t = tables[0]["main_eb_alfred"]
    md, tex, html = to_markdown(t), to_latex(t), to_html(t)
    assert "| Backbone | Method |" in md and "±" in md
    assert r"\begin{tabular}" in tex and r"$\pm$" in tex and r"\toprule" in tex and "_" not in tex.replace(r"\_", "")
    assert "<table>" in html and "&lt;" not in t.title
    rows = list(csv.DictReader(io.StringIO(to_csv(t))))
    wm = next(r for r in rows if r["Method"] == "worldmind")
    assert float(wm["SR Base"]) == _row(t, Method="worldmind")["SR Base"].value and wm["SR Base_sd"] != ""
    assert isinstance(_row(t, Method="worldmind")["SR Base"], Num)


def test_write_report_every_format(tables, tmp_path) -> None:
    out = tmp_path / "report"
    result = write_report(list(tables[1]), formats=["md", "latex", "csv", "html"], out=out)
    keys = {t.key for t in result["tables"]}
    assert {"main_eb_alfred", "ablation", "controlled_ablation", "transfer", "robustness", "task_order",
            "taxonomy", "overhead", "comparisons", "streams"} <= keys
    assert (out / "tables.md").read_text().count("### ") == len(result["tables"])
    assert (out / "tables.tex").read_text().count(r"\begin{table*}") == len(result["tables"])
    assert {p.stem for p in (out / "csv").glob("*.csv")} == keys
    for name in ("bars_eb_alfred", "memory_budget_eb_alfred_seeded-random_worldmind", "transfer_heatmap",
                 "taxonomy", "learning_eb_alfred"):
        for ext in ("png", "svg"):
            assert (out / "figures" / f"{name}.{ext}").stat().st_size > 1000, name
    assert (out / "site" / "index.html").exists()


def test_run_table_says_where_the_numbers_come_from() -> None:
    from worldmind_local.report import format_results

    row = {"benchmark": "eb_alfred", "method": "worldmind", "planner": "random:seeded-random", "seed": 0,
           "options": {}, "memory_budget": 0, "perturb": "rename", "subsets": {"base": {"SR": 50.0, "GC": 62.5,
                                                                                        "episodes": 2}},
           "avg": {"SR": 50.0, "GC": 62.5}}
    text = format_results({"table": [row], "streams": []}, env="twin")
    assert text.splitlines()[0] == "SR and GC in percent; env: symbolic twin (not the real simulator)"
    assert "worldmind Mem0 rename" in text and "50.0" in text and "62.5" in text
