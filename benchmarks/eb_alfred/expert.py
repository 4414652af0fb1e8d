"""ALFRED's expert plan (`plan.high_pddl`) translated into EB-ALFRED action names.

ALFRED's subgoals are coarser than EB's skills (a PickupObject from a closed drawer includes opening
it; HeatObject is a whole microwave routine), so the translation runs the plan on the twin and picks
each EB action from the state it is in: navigate with `find a <instance>` (the exact instance name
where EB has one), open what is closed, and check after every action that it succeeded and did what
the subgoal meant. A translation that cannot be carried out raises ExpertError naming the task, the
subgoal and EB's feedback, so a twin or data problem is never hidden.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from benchmarks.eb_alfred.actions import PUT_ACTION
from benchmarks.eb_alfred.goals import conditions_met
from benchmarks.eb_alfred.scene import Scene
from benchmarks.eb_alfred.skills import Skills
from benchmarks.eb_alfred.world import VISIBILITY_DISTANCE_SQ, World

__all__ = ["ExpertError", "expert_plan"]


class ExpertError(RuntimeError):
    """The expert plan could not be translated or executed on the twin."""


class _Executor:
    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.world = World(scene)
        self.skills = Skills(self.world)
        self.actions: list[str] = []
        self.alias: dict[int, int] = {}
        self.where = ""

    # -- running ---------------------------------------------------------------------------------
    def do(self, action: str) -> None:
        k = self.scene.action_index.get(action)
        if k is None:
            raise ExpertError(f"{self.scene.key}: {self.where}: {action!r} is not in the action space")
        verb, arg = self.scene.compiled[k]
        if verb not in ("put", "open"):
            self.skills.cur_receptacle = None
        handler = getattr(self.skills, verb)
        msg = handler() if verb in ("put", "drop") else handler(arg)
        if msg:
            raise ExpertError(f"{self.scene.key}: {self.where}: {action!r} failed: {msg}")
        self.actions.append(action)

    def idx(self, object_id: str) -> int:
        i = self.scene.index_of.get(object_id)
        if i is None:
            raise ExpertError(f"{self.scene.key}: {self.where}: unknown objectId {object_id!r}")
        return self.alias.get(i, i)

    # -- names -----------------------------------------------------------------------------------
    def find_action(self, i: int) -> str | None:
        o = self.scene.objects[i]
        base = self.scene.objects[o.slice_of] if o.slice_of >= 0 else o
        for name in (self.scene.names.id_to_name.get(base.object_id), base.prefix):
            if name and f"find a {name}" in self.scene.action_index:
                return f"find a {name}"
        return None

    def instance_name(self, i: int) -> str:
        o = self.scene.objects[i]
        return self.scene.names.id_to_name.get(o.object_id, o.prefix)

    # -- building blocks ---------------------------------------------------------------------------
    def outer_closed(self, i: int) -> int:
        w, j, found = self.world, self.world.parent[i], -1
        while j >= 0:
            if w.objs[j].openable and not w.is_open[j]:
                found = j
            j = w.parent[j]
        return found

    def lands(self, action: str | None) -> int:
        """Where `action` (a find) would take the agent now, without doing it; -1 if nowhere."""
        if action is None or action not in self.scene.action_index:
            return -1
        verb, arg = self.scene.compiled[self.scene.action_index[action]]
        return self.skills.locate(arg)[0] if verb == "find" else -1

    def sees(self, j: int, i: int) -> bool:
        w = self.world
        (ax, _, az), (x, _, z) = w.pos[j], w.pos[i]
        return (ax - x) ** 2 + (az - z) ** 2 <= VISIBILITY_DISTANCE_SQ and not w.enclosed(i)

    def goto(self, i: int, *, to_put: bool = False) -> None:
        """Stand where object i can be seen (opening what encloses it), or, to put into i, at i."""
        closed = self.outer_closed(i)
        if closed >= 0:
            self.goto(closed)
            self.open(closed)
            if not to_put:
                return
        options = [self.find_action(i)]
        if not to_put:
            j = self.world.parent[i]
            while j >= 0:
                options.append(self.find_action(j))
                j = self.world.parent[j]
        for action in options:
            j = self.lands(action)
            if j >= 0 and (to_put or self.sees(j, i)):
                self.do(action or "")
                return
        raise ExpertError(f"{self.scene.key}: {self.where}: no find action reaches {self.scene.objects[i].object_id}")

    def open(self, i: int) -> None:
        if self.world.objs[i].openable and not self.world.is_open[i]:
            self.do(f"open the {self.instance_name(i)}")

    def close(self, i: int) -> None:
        if self.world.objs[i].openable and self.world.is_open[i]:
            self.do(f"close the {self.instance_name(i)}")

    def pick(self, i: int) -> int:
        self.goto(i)
        want = self.scene.objects[i]
        self.do(f"pick up the {want.prefix}")
        got = self.world.holding
        if self.world.objs[got].type != want.type:
            raise ExpertError(f"{self.scene.key}: {self.where}: picked {self.world.objs[got].object_id}, wanted {want.type}")
        self.alias[i] = got
        return got

    def put(self, r: int) -> int:
        held = self.world.holding
        if held < 0:
            raise ExpertError(f"{self.scene.key}: {self.where}: put with empty hands")
        self.goto(r, to_put=True)
        self.open(r)
        self.do(PUT_ACTION)
        into = self.world.parent[held]
        if into < 0 or self.world.objs[into].type != self.scene.objects[r].type:
            raise ExpertError(f"{self.scene.key}: {self.where}: object went into {into}, wanted {self.scene.objects[r].type}")
        return held

    # -- ALFRED subgoals ---------------------------------------------------------------------------
    def run(self, pa: Mapping[str, Any]) -> None:
        act = pa["action"]
        if act == "PickupObject":
            self.pick(self.idx(pa["objectId"]))
        elif act == "PutObject":
            self.put(self.idx(pa["receptacleObjectId"]))
        elif act == "SliceObject":
            self.slice(self.idx(pa["objectId"]))
        elif act == "ToggleObject":
            target = self.idx(pa["objectId"])
            self.goto(target)
            self.do(f"turn on the {self.scene.objects[target].prefix}")
        elif act in ("HeatObject", "CoolObject"):
            self.heat_or_cool(self.idx(pa["objectId"]), heat=act == "HeatObject")
        elif act == "CleanObject":
            self.clean(self.idx(pa["objectId"]))
        elif act not in ("GotoLocation", "NoOp", "End"):
            raise ExpertError(f"{self.scene.key}: {self.where}: unknown subgoal {act!r}")

    def slice(self, target: int) -> None:
        """Slice; EB slices the nearest object of the type, so later subgoals follow the one cut."""
        self.goto(target)
        before = set(i for i, on in enumerate(self.world.active) if on)
        self.do(f"slice the {self.scene.objects[target].prefix}")
        cut = [i for i in before if not self.world.active[i]]
        if len(cut) != 1 or self.scene.objects[cut[0]].type != self.scene.objects[target].type:
            raise ExpertError(f"{self.scene.key}: {self.where}: slicing did not cut a {self.scene.objects[target].type}")
        if cut[0] != target:
            self.alias[target] = cut[0]
            for mine, theirs in zip(self.scene.objects[target].slices, self.scene.objects[cut[0]].slices, strict=False):
                self.alias[mine] = theirs

    def heat_or_cool(self, appliance: int, *, heat: bool) -> None:
        held = self.put(appliance)
        name = self.instance_name(appliance)
        self.close(appliance)
        if heat:
            self.do(f"turn on the {name}")
            self.do(f"turn off the {name}")
        self.open(appliance)
        self.do(f"pick up the {self.scene.objects[held].prefix}")
        if self.world.holding != held:
            raise ExpertError(f"{self.scene.key}: {self.where}: did not take the same object back")
        self.close(appliance)

    def clean(self, basin: int) -> None:
        held = self.put(basin)
        self.do("find a Faucet")
        self.do("turn on the Faucet")
        self.do("turn off the Faucet")
        if held not in self.world.cleaned:
            raise ExpertError(f"{self.scene.key}: {self.where}: faucet did not clean {self.scene.objects[held].object_id}")
        self.pick(held)


def expert_plan(scene: Scene, high_pddl: Sequence[Mapping[str, Any]]) -> list[str]:
    """EB action names that carry out ALFRED's expert subgoals on this scene."""
    ex = _Executor(scene)
    for k, step in enumerate(high_pddl):
        pa = step.get("planner_action", step)
        ex.where = f"subgoal {k} {pa.get('action')}"
        ex.run(pa)
    s, ts = conditions_met(scene.goal, ex.world)
    if s != ts:
        raise ExpertError(f"{scene.key}: the expert plan ends with {s}/{ts} goal conditions met")
    return ex.actions
