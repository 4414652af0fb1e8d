"""EB-ALFRED: EmbodiedBench's household tasks (ALFRED / AI2-THOR) behind the shared Env contract.

`ADAPTER` loads EmbodiedBench's episodes, generates procedural suites, and makes the `twin` (symbolic,
always available) or the `embodiedbench` env (the real simulator, optional). Where things live:
actions.py (action space and instance names), data.py (data pack), scene.py (initial scenes: which
facts are exact and which are completed), world.py / skills.py / twin.py (the twin), goals.py (success
and progress), expert.py (ALFRED's expert plans as EB actions), generator.py / layouts.py /
phrasing.py (generated suites), state_text.py (the abstract state), nl_steps.py (EB's NL-Steps
oracle plans), embodiedbench.py (the real-simulator wrapper).
"""

from benchmarks.eb_alfred.adapter import AlfredAdapter

__all__ = ["ADAPTER", "AlfredAdapter"]

ADAPTER = AlfredAdapter()
