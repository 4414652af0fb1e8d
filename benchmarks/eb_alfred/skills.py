"""EB-ALFRED's high-level skills on the twin's world, with EmbodiedBench's exact messages.

Each skill returns EB's message: '' on success, else the text that follows 'Last action is invalid. '.
The choices of which instance a skill acts on follow EB's ThorConnector: the nearest object of the
type (matching the objectId's first field, case-insensitively), with its penalties (+100000 when a
closed receptacle holds it, +1000 when not visible where visibility is preferred, +10000 for a
StoveBurner that holds something, -100 for slice pieces once something was sliced).

What AI2-THOR itself refuses is modelled as preconditions: interacting needs the target visible;
pick up needs an empty hand; put needs a receptacle that is open (EB puts with forceAction, which
skips AI2-THOR's visibility check and its type-placement restrictions, not the closed-door check);
a Microwave turns on only when closed; slicing needs a knife in hand. Physics the twin cannot
simulate is replaced by a rule: a put lands beside what is already in the receptacle, and a drop
lands in the receptacle in front of the agent (see drop). Two EB quirks are kept per episode rather
than per process (EB never resets them between episodes): the put counter behind the forced drop,
and the 'something was sliced' flag.
"""

from __future__ import annotations

from benchmarks.eb_alfred.typefacts import KNIFE_TYPES, ithor_name
from benchmarks.eb_alfred.world import World

__all__ = ["Skills"]

_SPOTS = ((0.0, 0.0), (0.1, 0.0), (-0.1, 0.0), (0.0, 0.1), (0.0, -0.1), (0.1, 0.1), (-0.1, -0.1), (0.1, -0.1), (-0.1, 0.1))


class Skills:
    """The skill implementations. `world` is swapped in by the twin (copy-on-write)."""

    def __init__(self, world: World) -> None:
        self.world = world
        self.cur_receptacle: str | None = None
        self.put_counts: dict[str, int] = {}
        self.sliced = False
        self.changed = False  # set when the world changed (progress must be recomputed)
        self.before_write = lambda: None  # the twin's copy-on-write hook

    # -- lookup ----------------------------------------------------------------------------------
    def nearest(
        self,
        name: str,
        *,
        pickupable: bool = False,
        toggleable: bool = False,
        inherited: bool = False,
        prefer_visible: bool = False,
        prefer_sliced: bool = False,
        exclude: int = -1,
    ) -> int:
        """EB's get_obj_id_from_name (including its odd pre-penalty distance test)."""
        w = self.world
        objs, active = w.objs, w.active
        stove = name.casefold() == "stoveburner"
        best, best_cost = -1, 1e8
        for i in w.scene.by_prefix.get(name.casefold(), ()):
            o = objs[i]
            if i == exclude or not active[i]:
                continue
            if (pickupable and not o.pickupable) or (toggleable and not o.toggleable) or (inherited and not o.inherited):
                continue
            d = w.distance(i)
            if d >= best_cost:
                continue
            cost = d
            if w.in_closed_holder(i):
                cost += 100000
            if stove and w.has_contents(i):
                cost += 10000
            if prefer_visible and not w.visible(i):
                cost += 1000
            if prefer_sliced and o.slice_of >= 0:
                cost -= 100
            if cost < best_cost:
                best, best_cost = i, cost
        return best

    def label(self, i: int) -> str:
        """How EB names a receptacle in its messages: the instance name, else the id's type field."""
        o = self.world.objs[i]
        return self.world.scene.names.id_to_name.get(o.object_id, o.prefix)

    # -- moves -------------------------------------------------------------------------------------
    def _write(self) -> World:
        self.before_write()
        self.changed = True
        return self.world

    def _move(self, i: int, new_parent: int, where: tuple[float, float, float]) -> None:
        w = self._write()
        moving = [i, *w.contents(i)]
        w.parent[i] = new_parent
        w.also_in[i] = ()
        for j in moving:
            w.pos[j] = where

    # -- skills ------------------------------------------------------------------------------------
    def find(self, arg: str) -> str:
        self.cur_receptacle = arg
        idx, target = self.locate(arg)
        if idx < 0:
            return f"Cannot find {target}. This object may not exist in this scene. Try to explore other instances instead."
        self._go_to(idx)
        return ""

    def locate(self, arg: str) -> tuple[int, str]:
        """Where `find a <arg>` takes the agent (-1: nowhere) and the name EB's message uses."""
        w = self.world
        name = ithor_name(arg)
        if "|" in name:
            target = name.split("|")[0]
            idx = w.scene.index_of.get(name, -1)
            tmp = self.nearest(target, prefer_visible=True, prefer_sliced=self.sliced)
            if tmp >= 0 and "Sliced" in w.objs[tmp].object_id and name in w.objs[tmp].object_id:
                idx = tmp
        else:
            target = name
            idx = self.nearest(name, prefer_visible=True, prefer_sliced=self.sliced)
        if idx >= 0 and not w.active[idx]:
            idx = -1
        return idx, target

    def _go_to(self, idx: int) -> None:
        w = self._write()
        w.agent = w.agent_at(idx)
        w.location = w.scene.display[idx]
        chain = [idx] if w.objs[idx].receptacle else []
        j = w.parent[idx]
        while j >= 0:
            chain.append(j)
            j = w.parent[j]
        w.place = tuple(chain)
        for j in w.carried():
            w.pos[j] = w.agent

    def pick(self, arg: str) -> str:
        w = self.world
        name = ithor_name(arg)
        idx = self.nearest(name, pickupable=True, prefer_visible=True, prefer_sliced=self.sliced)
        if idx < 0:
            return f"Cannot find {name} to pick up. Find the object before picking up it"
        if not w.visible(idx):
            holders = ([w.parent[idx]] if w.parent[idx] >= 0 else []) + list(w.also_in[idx])
            if holders:
                return f"{name} is not visible because it is in {self.label(holders[0])}. Go there to pick the object instead."
        if not w.visible(idx) or w.holding >= 0:
            return self._hands_message()
        self._move(idx, -1, w.agent)
        self.world.holding = idx
        return ""

    def _hands_message(self) -> str:
        w = self.world
        if w.holding < 0:
            return "Robot is not holding any object"
        return f"Robot is currently holding {w.objs[w.holding].type}"

    def put(self) -> str:
        if self.cur_receptacle is None:
            return self.drop()
        key = self.cur_receptacle
        self.put_counts[key] = self.put_counts.get(key, 0) + 1
        msg = self._put_into(ithor_name(key))
        if len(msg) > 16 and self.put_counts[key] >= 3:
            self.drop()
            msg += ". The robot dropped the object instead."
        return msg

    def _put_into(self, orig: str) -> str:
        w = self.world
        if w.holding < 0:
            return "Robot is not holding any object"
        recep_name, msg, last, exclude = orig, "", -1, -1
        for k in (0, 1):
            for i in (0, 1):
                if k == 1 and exclude < 0:
                    exclude = last
                if k == 0 and "|" in orig:
                    if i == 1:
                        continue
                    r = w.scene.index_of.get(orig, -2)
                    recep_name = orig.split("|")[0]
                else:
                    sinkish = "Sink" in recep_name or "Bathtub" in recep_name
                    r = self.nearest(recep_name, inherited=(i == 0) == sinkish, exclude=exclude)
                if r == -1:
                    msg = (f"Putting the object on {recep_name} failed. First check whether the receptacle is "
                           "open or not. Also try other instances of the receptacle")
                    continue
                last = r
                if r >= 0 and self._can_put(w.holding, r):
                    self._move(w.holding, r, self._spot(r))
                    self.world.holding = -1
                    return ""
                msg = (f"Putting the object on {recep_name} failed. First check the receptacle is open or not. "
                       "Also try other instances of the receptacle")
        return msg

    def _can_put(self, obj: int, r: int) -> bool:
        w = self.world
        ro = w.objs[r]
        if not (w.active[r] and ro.receptacle) or r == obj or obj in w.holders(r):
            return False
        if (ro.openable and not w.is_open[r]) or w.enclosed(r):
            return False
        return True

    def _spot(self, r: int) -> tuple[float, float, float]:
        """Where a put lands: the receptacle's position, nudged so that objects put into the same
        receptacle do not share one point (AI2-THOR places them side by side)."""
        w = self.world
        k = sum(1 for j, p in enumerate(w.parent) if p == r and w.active[j])
        dx, dz = _SPOTS[k % len(_SPOTS)]
        x, y, z = w.pos[r]
        return (x + dx, y, z + dz)

    def drop(self) -> str:
        """Let go of the held object. It falls onto the receptacle the agent faces: the one found
        last, or the one holding what was found last (AI2-THOR drops it in front of the camera);
        with none, or a closed one, it lands on the floor."""
        w = self.world
        if w.holding < 0:
            return "Robot is not holding any object"
        carried = set(w.carried())
        for r in w.place:
            if r not in carried and w.active[r] and not (w.objs[r].openable and not w.is_open[r]) and not w.enclosed(r):
                self._move(w.holding, r, self._spot(r))
                break
        else:
            x, _, z = w.agent
            self._move(w.holding, -1, (x, 0.0, z))
        self.world.holding = -1
        return ""

    def _target(self, arg: str) -> tuple[int, str]:
        """open/close resolve an exact objectId when EB mapped the name, else the nearest of the type."""
        name = ithor_name(arg)
        if "|" in name:
            return self.world.scene.index_of.get(name, -2), name.split("|")[0]
        return self.nearest(name), name

    def open(self, arg: str) -> str:
        w = self.world
        idx, name = self._target(arg)
        if idx == -1:
            return f"Cannot find {name} to open. Find the object before opening it"
        ok = idx >= 0 and w.objs[idx].openable and not w.is_open[idx] and w.visible(idx)
        if not ok:
            already = idx >= 0 and w.active[idx] and w.objs[idx].openable and w.is_open[idx]
            return f"Open action failed. The {name} is already open" if already else "Open action failed."
        self._write().is_open[idx] = True
        return ""

    def close(self, arg: str) -> str:
        w = self.world
        idx, name = self._target(arg)
        if idx == -1:
            return f"Cannot find {name} to close"
        if not (idx >= 0 and w.objs[idx].openable and w.is_open[idx] and w.visible(idx)):
            closed = idx >= 0 and w.active[idx] and w.objs[idx].openable and not w.is_open[idx]
            return "Close action failed" + (f". The {name} is already closed" if closed else "")
        self._write().is_open[idx] = False
        if "Fridge" in w.objs[idx].object_id:
            fridge = w.scene.first_of_type("Fridge")
            self.world.cooled = self.world.cooled | frozenset(self.world.contents(fridge))
        return ""

    def turn_on(self, arg: str) -> str:
        w = self.world
        name = ithor_name(arg)
        idx = self.nearest(name, toggleable=True)
        if idx < 0:
            return f"Cannot find {name} to turn on"
        o = w.objs[idx]
        if w.is_on[idx] or not w.visible(idx) or (o.type == "Microwave" and w.is_open[idx]):
            return "Turn on action failed"
        self._write().is_on[idx] = True
        w = self.world
        if "Faucet" in o.object_id:
            basin = self._closest_visible_basin(idx)
            if basin < 0:  # ALFRED raises here; EB reports a failed turn-on (the faucet is on)
                return "Turn on action failed"
            w.cleaned = w.cleaned | frozenset(w.contents(basin))
        if "Microwave" in o.object_id:
            w.heated = w.heated | frozenset(w.contents(w.scene.first_of_type("Microwave")))
        return ""

    def _closest_visible_basin(self, faucet: int) -> int:
        w = self.world
        basins = [o.idx for o in w.objs if "SinkBasin" in o.type and w.visible(o.idx)]
        ref = w.pos[faucet]
        return min(basins, key=lambda b: (sum((a - c) ** 2 for a, c in zip(w.pos[b], ref, strict=True)), b), default=-1)

    def turn_off(self, arg: str) -> str:
        w = self.world
        name = ithor_name(arg)
        idx = self.nearest(name, toggleable=True)
        if idx < 0:
            return f"Cannot find {name} to turn off"
        if not w.is_on[idx] or not w.visible(idx):
            return "Turn off action failed"
        self._write().is_on[idx] = False
        return ""

    def slice(self, arg: str) -> str:
        try:
            return self._slice(ithor_name(arg))
        finally:
            self.sliced = True

    def _slice(self, name: str) -> str:
        w = self.world
        idx = self.nearest(name)
        if idx < 0:
            return f"Cannot find {name} to slice"
        o = w.objs[idx]
        knife = w.holding >= 0 and w.objs[w.holding].type in KNIFE_TYPES
        if not (o.sliceable and knife and idx != w.holding and w.visible(idx)):
            return "Slice action failed"
        w = self._write()
        w.active[idx] = False
        for s in o.slices:
            w.active[s], w.parent[s], w.pos[s], w.also_in[s] = True, w.parent[idx], w.pos[idx], w.also_in[idx]
        return ""

    def unsupported(self, arg: str) -> str:
        return "instruction not supported"
