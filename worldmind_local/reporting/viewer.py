"""The episode viewer: a static site (plain files, relative links, no server, no network, no CDN).

```
site/index.html        runs overview, every table, every figure, links to the streams
site/s<k>.html         one stream: spec, episodes with outcome, the experience it wrote (with links)
site/s<k>-e<i>.html    one episode: instruction, each model call's prompt and answer (from the run's
                       cache.sqlite), each action with its feedback, predicted vs actual state, the
                       judge's verdict and the rules, the experience written and retrieved
site/viewer.css|js     style, and arrow-key navigation between episodes
site/figures/          the report's figures (copied, so the folder stands alone)
```

An experience entry links to the episode that wrote it (from the stream page and from any episode that
retrieved it, across every loaded run, so a transfer run links back into its source run); a poisoned
entry is marked and shows the rule it replaced.
"""

from __future__ import annotations

import html
import json
import shutil
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import worldmind_local.reporting.episodes as ep
from worldmind_local.reporting.load import Run, Stream
from worldmind_local.reporting.model import Table, short_model
from worldmind_local.reporting.render import to_html

__all__ = ["write_site"]

e = html.escape


def _page(title: str, body: str, *, crumbs: str = "") -> str:
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">'
            f'<link rel="icon" href="data:,"><title>{e(title)}</title>'
            f'<link rel="stylesheet" href="viewer.css"></head><body>'
            f'<header class="top"><h1>{e(title)}</h1><a href="index.html">overview</a>{crumbs}</header>'
            f"<main>{body}</main><script src=\"viewer.js\"></script></body></html>\n")


def _badge(ok: bool, text: str) -> str:
    return f'<span class="badge {"ok" if ok else "fail"}">{e(text)}</span>'


class _Calls:
    """Prompts and answers of a run, read from its cache.sqlite (absent cache: nothing shown)."""

    def __init__(self, run: Run) -> None:
        self.cache = None
        path = run.path / "cache.sqlite"
        if path.exists():
            try:
                from models.cache import ResponseCache

                self.cache = ResponseCache(path, create=False)
            except Exception:  # a damaged cache only hides prompts; the rest of the viewer stands
                self.cache = None

    def render(self, call: dict[str, Any], anchor: str) -> str:
        head = (f'<details id="{anchor}"><summary>{e(str(call.get("key")))} &middot; {e(str(call.get("role")))} '
                f'&middot; {e(str(call.get("model", "")))} &middot; {call.get("prompt_tokens", 0)}+'
                f'{call.get("completion_tokens", 0)} tokens</summary>')
        if self.cache is None:
            return head + "<p class=\"note\">no cache.sqlite in this run (made with --no-cache?)</p></details>"
        request = self.cache.get_request(str(call.get("request")))
        answer = self.cache.get(str(call.get("request")))
        parts = [head]
        for m in (request or {}).get("messages", []):
            content = m.get("content")
            if not isinstance(content, str):
                content = "\n".join(p.get("text", f"[{p.get('type')} {str(p.get('sha256', ''))[:12]}]")
                                    for p in content or [])
            parts.append(f"<h4>{e(str(m.get('role')))}</h4><pre>{e(content)}</pre>")
        if request is None:
            parts.append('<p class="note">prompt not stored in the cache</p>')
        texts = answer.texts if answer is not None else []
        parts.append("<h4>answer</h4>" + "".join(f"<pre>{e(t)}</pre>" for t in texts)
                     if texts else '<p class="note">no answer stored</p>')
        return "".join(parts) + "</details>"

    def close(self) -> None:
        if self.cache is not None:
            self.cache.close()


class Site:
    def __init__(self, runs: Sequence[Run], out: Path) -> None:
        self.runs = runs
        self.out = out
        self.streams: list[Stream] = [s for r in runs for s in r.streams]
        self.page_of = {id(s): f"s{k}" for k, s in enumerate(self.streams)}
        self.made_by: dict[str, str] = {}     # experience id -> episode page#anchor
        self.poisoned: dict[str, dict[str, Any]] = {}
        for s in self.streams:
            for i, rec in enumerate(s.records):
                for item in rec.get("experience") or []:
                    self.made_by.setdefault(str(item.get("id")), f"{self.page_of[id(s)]}-e{i}.html#exp-{item.get('id')}")
            for item in (s.poison or {}).get("replaced") or []:
                self.poisoned[str(item.get("poisoned_id"))] = item

    def exp_link(self, entry_id: str) -> str:
        label = e(entry_id)
        if entry_id in self.poisoned:
            original = self.poisoned[entry_id].get("original") or {}
            return (f'<span class="badge poisoned" title="replaced: {e(str(original.get("text", "")))}">'
                    f"{label} poisoned</span>")
        target = self.made_by.get(entry_id)
        return f'<a href="{e(target)}">{label}</a>' if target else f"{label} (seed memory)"

    # -- pages -------------------------------------------------------------------------------------

    def index(self, tables: Sequence[Table], figures: Sequence[Any]) -> str:
        rows = []
        for s in self.streams:
            sr, gc = ep.sr(s.records), ep.gc(s.records)
            rows.append(f'<tr><td><a href="{self.page_of[id(s)]}.html">{e(s.stream_id)}</a></td><td>{e(s.run)}</td>'
                        f"<td>{e(s.label)}</td><td>{e(_variant(s))}</td><td>{e(str(s.spec.get('subset')))}</td>"
                        f"<td>{e(short_model(s.spec.get('planner')))}</td><td class=\"num\">{s.spec.get('seed')}</td>"
                        f"<td class=\"num\">{len(s.records)}</td><td class=\"num\">{_fmt(sr.value)}</td>"
                        f"<td class=\"num\">{_fmt(gc.value)}</td><td>{e(s.status or '')}</td></tr>")
        runs = "".join(
            f"<li><b>{e(r.run_id)}</b> ({e(str(r.path))}): {len(r.streams)} stream(s); env: "
            f"{'symbolic twin (not the real simulator)' if r.env == 'twin' else e(r.env)}; command: "
            f"<code>{e(str(r.manifest.get('command_line', '')))}</code></li>" for r in self.runs)
        figs = "".join(f'<figure><img src="figures/{e(f.files[0].name)}" alt="{e(f.title)}">'
                       f"<figcaption><b>{e(f.title)}</b>. {e(f.caption)}</figcaption></figure>" for f in figures)
        body = (f"<section><h2>Runs</h2><ul>{runs}</ul></section>"
                f'<section><h2>Streams</h2><div class="scroll"><table id="streams-list"><thead><tr><th>Stream</th>'
                f"<th>Run</th><th>Method</th><th>Variant</th><th>Subset</th><th>Planner</th><th>Seed</th><th>Episodes</th>"
                f"<th>SR</th><th>GC</th><th>Status</th></tr></thead><tbody>{''.join(rows)}</tbody></table></div>"
                f"</section><section><h2>Figures</h2>{figs or '<p>none</p>'}</section>"
                + "".join(to_html(t) for t in tables))
        return _page("WorldMind-Local report", body)

    def stream_page(self, s: Stream) -> str:
        page = self.page_of[id(s)]
        rows = []
        for i, rec in enumerate(s.records):
            rows.append(f'<tr><td><a href="{page}-e{i}.html">{i}</a></td><td class="num">{rec.get("index")}</td>'
                        f"<td>{e(str(rec.get('instruction', '')))}</td>"
                        f"<td>{_badge(bool(rec.get('success')), 'success' if rec.get('success') else str(rec.get('taxonomy')))}</td>"
                        f"<td class=\"num\">{_fmt(100 * float(rec.get('progress') or 0))}</td>"
                        f"<td class=\"num\">{rec.get('steps', 0)}</td><td class=\"num\">{len(rec.get('calls') or [])}</td>"
                        f"<td class=\"num\">{len(rec.get('experience') or [])}</td></tr>")
        exp = []
        for i, rec in enumerate(s.records):
            for item in rec.get("experience") or []:
                exp.append(f'<tr id="exp-{e(str(item.get("id")))}"><td>{e(str(item.get("id")))}</td>'
                           f"<td>{e(str(item.get('partition', item.get('kind', ''))))}</td>"
                           f"<td>{'kept' if item.get('kept') else 'discarded'}</td><td>{e(str(item.get('text', '')))}</td>"
                           f'<td><a href="{page}-e{i}.html#exp-{e(str(item.get("id")))}">episode {i}</a></td></tr>')
        poison = ""
        if s.poison:
            items = "".join(f"<tr><td>{it.get('position')}</td><td>{e(str(it.get('poisoned_id')))}</td>"
                            f"<td>{e(str((it.get('original') or {}).get('text', '')))}</td>"
                            f"<td>{e(str(it.get('poisoned_text', '')))}</td></tr>" for it in s.poison.get("replaced") or [])
            poison = (f"<section><h2>Poisoned seed memory ({s.poison.get('poisoned')} of {s.poison.get('entries')} "
                      f"entries, rate {s.poison.get('rate')}, seed {s.poison.get('seed')})</h2><table><thead><tr>"
                      f"<th>Position</th><th>Poisoned id</th><th>Original rule</th><th>Poisoned rule</th></tr></thead>"
                      f"<tbody>{items}</tbody></table></section>")
        spec = "".join(f"<div>{e(k)}</div><div>{e(json.dumps(v))}</div>" for k, v in s.spec.items())
        body = (f'<section><h2>Spec</h2><div class="kv"><div>run</div><div>{e(s.run)}</div>'
                f"<div>env</div><div>{'symbolic twin' if s.env == 'twin' else e(s.env)}</div><div>suite</div>"
                f"<div>{e(s.suite)}</div>{spec}</div></section>"
                f'<section><h2>Episodes (in the order run)</h2><table id="episodes"><thead><tr><th>#</th><th>Index</th>'
                f"<th>Instruction</th><th>Outcome</th><th>GC</th><th>Steps</th><th>Calls</th><th>Experience</th></tr>"
                f"</thead><tbody>{''.join(rows)}</tbody></table></section>{poison}"
                f"<section><h2>Experience written</h2><table><thead><tr><th>Id</th><th>Partition</th><th>Commit</th>"
                f"<th>Text</th><th>Made by</th></tr></thead><tbody>{''.join(exp) or '<tr><td>none</td></tr>'}"
                f"</tbody></table></section>")
        return _page(s.stream_id, body)

    def episode_page(self, s: Stream, i: int, calls: _Calls) -> str:
        page = self.page_of[id(s)]
        rec = s.records[i]
        prev = f'<a id="prev" href="{page}-e{i - 1}.html">&larr; previous</a>' if i > 0 else \
            '<span class="disabled">&larr; previous</span>'
        nxt = f'<a id="next" href="{page}-e{i + 1}.html">next &rarr;</a>' if i + 1 < len(s.records) else \
            '<span class="disabled">next &rarr;</span>'
        nav = (f'<nav class="episodes">{prev}<a id="up" href="{page}.html">stream</a>{nxt}'
               f"<span>episode {i + 1} of {len(s.records)}</span></nav>")
        call_list = rec.get("calls") or []
        anchors = {str(c.get("key")): f"call-{j}" for j, c in enumerate(call_list)}
        outcome = (f'<section><h2>Task</h2><div class="kv"><div>instruction</div><div id="instruction">'
                   f"{e(str(rec.get('instruction', '')))}</div><div>task</div><div>{e(str(rec.get('task_id')))} "
                   f"({e(str(rec.get('task_type')))})</div><div>outcome</div><div>"
                   f"{_badge(bool(rec.get('success')), 'success' if rec.get('success') else str(rec.get('taxonomy')))} "
                   f"GC {_fmt(100 * float(rec.get('progress') or 0))}, {rec.get('steps', 0)} steps, end: "
                   f"{e(str(rec.get('end_reason')))}</div><div>retrieved</div><div>"
                   f"{', '.join(self.exp_link(str(x)) for x in rec.get('retrieved_ids') or []) or 'nothing'}</div>"
                   f"</div></section>")
        plans = []
        steps_by_plan: dict[int, list[dict[str, Any]]] = {}
        for step in rec.get("trajectory") or []:
            steps_by_plan.setdefault(int(step.get("plan_index", 0)), []).append(step)
        for plan in rec.get("plans") or []:
            k = int(plan.get("index", 0))
            link = anchors.get(f"planner:{k}")
            plans.append(f'<section class="plan" id="plan-{k}"><h3>Plan {k} ({e(str(plan.get("status")))}, '
                         f"{plan.get('n_actions', 0)} action(s))"
                         + (f' &middot; <a href="#{link}">prompt and answer</a>' if link else "")
                         + f"</h3><p>{e(str(plan.get('language_plan', '')))}</p>"
                         + (f"<pre>{e(str(plan.get('error')))}</pre>" if plan.get("error") else "")
                         + "".join(self._step(st, anchors) for st in steps_by_plan.get(k, [])) + "</section>")
        written = "".join(
            f'<li id="exp-{e(str(it.get("id")))}"><b>{e(str(it.get("partition", it.get("kind", ""))))}</b> '
            f"({'kept' if it.get('kept') else 'discarded'}; "
            f'<a href="{page}.html#exp-{e(str(it.get("id")))}">in the stream</a>): {e(str(it.get("text", "")))}</li>'
            for it in rec.get("experience") or [])
        calls_html = "".join(calls.render(c, anchors[str(c.get("key"))]) for c in call_list)
        body = (nav + outcome + "".join(plans)
                + f"<section><h2>Experience written</h2><ul>{written or '<li>none</li>'}</ul></section>"
                + f"<section><h2>Model calls</h2>{calls_html or '<p>none</p>'}</section>" + nav)
        return _page(f"{s.stream_id} / episode {i}", body, crumbs=f'<a href="{page}.html">{e(s.stream_id)}</a>')

    def _step(self, st: dict[str, Any], anchors: dict[str, str]) -> str:
        verdict = st.get("judge_verdict")
        judge = anchors.get(f"judge:{st.get('step')}")
        reflector = anchors.get(f"reflector:{st.get('step')}")
        links = "".join(f' <a href="#{a}">{name}</a>' for name, a in (("judge", judge), ("reflector", reflector)) if a)
        rules = "".join(f"<li>{e(r)}</li>" for r in st.get("rules") or [])
        return (f'<div class="step{" invalid" if st.get("invalid") else ""}"><b>Step {st.get("step")}</b>: '
                f"[{st.get('action_id')}] {e(str(st.get('action_name')))}"
                + (f" (planner wrote {e(str(st.get('planned_name')))})" if st.get("planned_name") else "")
                + f'<div class="kv"><div>feedback</div><div>{e(str(st.get("feedback", "")))}</div>'
                f"<div>predicted state</div><div>{e(str(st.get('predicted_state') or '-'))}</div>"
                f"<div>actual state</div><div>{e(str(st.get('actual_state') or '-'))}</div>"
                f"<div>judge</div><div>"
                + (f'<span class="badge {e(verdict)}">{e(verdict)}</span> {e(str(st.get("judge_reason") or ""))}'
                   if verdict else "not verified")
                + f"{links}</div><div>progress</div><div>{_fmt(100 * float(st.get('progress') or 0))}</div></div>"
                + (f"<div>rules written:<ul>{rules}</ul></div>" if rules else "") + "</div>")


def _variant(s: Stream) -> str:
    """What sets a stream apart from a plain one: stress test, task order, budget, seed memory."""
    parts = [str(s.spec["perturb"])] if s.spec.get("perturb") else []
    if s.spec.get("task_order_seed") is not None:
        parts.append(f"order {s.spec['task_order_seed']}")
    if s.spec.get("memory_budget") is not None:
        parts.append(f"Mem{s.spec['memory_budget']}")
    if s.spec.get("memory_from"):
        parts.append("seed memory")
    return ", ".join(parts)


def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f}"


def write_site(runs: Sequence[Run], tables: Sequence[Table], figures: Sequence[Any], out: str | Path) -> list[Path]:
    """Write the site into `out`; returns the files written."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    static = resources.files("worldmind_local.reporting").joinpath("static")
    for name in ("viewer.css", "viewer.js"):
        (out / name).write_text(static.joinpath(name).read_text())
        files.append(out / name)
    if figures:
        (out / "figures").mkdir(exist_ok=True)
        for f in figures:
            for path in f.files:
                shutil.copyfile(path, out / "figures" / path.name)
    site = Site(runs, out)
    (out / "index.html").write_text(site.index(tables, figures))
    files.append(out / "index.html")
    for run in runs:
        calls = _Calls(run)
        try:
            for s in run.streams:
                page = site.page_of[id(s)]
                (out / f"{page}.html").write_text(site.stream_page(s))
                files.append(out / f"{page}.html")
                for i in range(len(s.records)):
                    (out / f"{page}-e{i}.html").write_text(site.episode_page(s, i, calls))
                    files.append(out / f"{page}-e{i}.html")
        finally:
            calls.close()
    return files
