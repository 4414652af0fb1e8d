"""Room layouts for generated EB-ALFRED scenes, in the same fact format as the data pack.

A room is a ring of *stations* (a sink counter, a stove, a desk with its lamp, ...) spaced more than
twice the visibility distance apart around a rectangle, so what can be seen from one station is what
stands at it, as in the real floor plans. Receptacle and object ids follow AI2-THOR's
`Type|x|y|z` form (sink and bathtub basins `Sink|x|y|z|SinkBasin`), so the twin reads their positions
exactly as it reads real ones. Which objects a receptacle may hold comes from ALFRED's table.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field
from typing import Any

from benchmarks.eb_alfred.typefacts import type_facts

__all__ = ["ROOMS", "Room", "build_room", "fmt_id"]

# station: [(type, count range)], static extras. Heights are the receptacle origins' y (m).
_HEIGHT = {
    "CounterTop": 0.95, "SinkBasin": 0.9, "StoveBurner": 0.95, "Cabinet": 0.4, "Drawer": 0.75, "Fridge": 0.0,
    "Microwave": 1.0, "CoffeeMachine": 0.95, "Toaster": 0.95, "DiningTable": 0.75, "GarbageCan": 0.0,
    "Shelf": 1.1, "Sofa": 0.4, "ArmChair": 0.4, "CoffeeTable": 0.45, "SideTable": 0.6, "TVStand": 0.5,
    "Bed": 0.5, "Desk": 0.75, "Dresser": 0.8, "LaundryHamper": 0.3, "Toilet": 0.4, "ToiletPaperHanger": 0.7,
    "BathtubBasin": 0.3, "TowelHolder": 1.2, "HandTowelHolder": 1.1, "Safe": 0.2, "Ottoman": 0.4,
}
_OPENABLE = frozenset({"Cabinet", "Drawer", "Fridge", "Microwave", "Safe"})

ROOMS: dict[str, dict[str, Any]] = {
    "Kitchen": {
        "stations": [
            [("CounterTop", (1, 1)), ("SinkBasin", (1, 1)), ("Cabinet", (1, 2)), ("Drawer", (1, 1))],
            [("StoveBurner", (2, 4)), ("Cabinet", (1, 1)), ("Drawer", (0, 1))],
            [("Fridge", (1, 1))],
            [("CounterTop", (1, 1)), ("Microwave", (1, 1)), ("CoffeeMachine", (1, 1)), ("Toaster", (0, 1)), ("Cabinet", (1, 2))],
            [("DiningTable", (1, 1))],
            [("GarbageCan", (1, 1))],
            [("Shelf", (0, 2))],
        ],
        "objects": ["Apple", "Bread", "Lettuce", "Potato", "Tomato", "Egg", "Knife", "ButterKnife", "Fork", "Spoon",
                    "Spatula", "Ladle", "Mug", "Cup", "Bowl", "Plate", "Pot", "Pan", "Kettle", "DishSponge",
                    "SaltShaker", "PepperShaker", "SoapBottle", "WineBottle"],
    },
    "LivingRoom": {
        "stations": [
            [("Sofa", (1, 1))], [("CoffeeTable", (1, 1))], [("ArmChair", (1, 1))],
            [("TVStand", (1, 1)), ("Drawer", (0, 2))], [("SideTable", (1, 1))], [("Shelf", (1, 3))],
            [("GarbageCan", (1, 1))], [("DiningTable", (0, 1))],
        ],
        "objects": ["RemoteControl", "KeyChain", "CreditCard", "Laptop", "Pillow", "Newspaper", "Statue", "Vase",
                    "Watch", "Box", "WateringCan", "TissueBox", "Book", "CellPhone", "Plate", "Bowl"],
    },
    "Bedroom": {
        "stations": [
            [("Bed", (1, 1))], [("Desk", (1, 1)), ("Drawer", (1, 2))], [("Dresser", (1, 1)), ("Drawer", (1, 2))],
            [("SideTable", (1, 1))], [("Shelf", (1, 3))], [("GarbageCan", (1, 1))], [("LaundryHamper", (0, 1))],
        ],
        "objects": ["AlarmClock", "Book", "CD", "CellPhone", "CreditCard", "KeyChain", "Laptop", "Pen", "Pencil",
                    "Pillow", "BaseballBat", "TennisRacket", "BasketBall", "Mug", "Bowl", "Box", "Watch"],
    },
    "Bathroom": {
        "stations": [
            [("CounterTop", (1, 1)), ("SinkBasin", (1, 1)), ("Cabinet", (1, 2)), ("Drawer", (0, 1))],
            [("Toilet", (1, 1)), ("ToiletPaperHanger", (1, 1))], [("BathtubBasin", (1, 1))],
            [("TowelHolder", (1, 1)), ("HandTowelHolder", (1, 1))], [("GarbageCan", (1, 1))], [("Shelf", (0, 2))],
        ],
        "objects": ["SoapBar", "SoapBottle", "SprayBottle", "Candle", "Cloth", "ToiletPaper", "HandTowel",
                    "Towel", "Plunger", "DishSponge", "TissueBox"],
    },
}
# Lamps lit by look_at tasks (static, toggleable), placed at a station.
_LAMPS = {"LivingRoom": ("FloorLamp", "SideTable"), "Bedroom": ("DeskLamp", "Desk")}


def fmt_id(obj_type: str, x: float, y: float, z: float, suffix: str = "") -> str:
    oid = f"{obj_type}|{x:+06.2f}|{y:+06.2f}|{z:+06.2f}"
    return f"{oid}|{suffix}" if suffix else oid


@dataclass
class Room:
    kind: str
    facts: dict[str, Any]
    receptacles: list[str] = field(default_factory=list)
    station_of: dict[str, int] = field(default_factory=dict)
    agent: tuple[float, float] = (0.0, 0.0)
    _taken: set[str] = field(default_factory=set)

    def add_object(self, obj_type: str, recep: str | None, rng: random.Random, x: float = 0.0, z: float = 0.0) -> str:
        """Place a new object in `recep` (or on the floor at x/z); returns its id."""
        props = list(type_facts()["object_props"].get(obj_type, ["pickupable"]))
        if recep is not None:
            x, y, z = (float(v) for v in recep.split("|")[1:4])
        else:
            y = 0.0
        for _ in range(50):
            oid = fmt_id(obj_type, x + rng.uniform(-0.3, 0.3), y + 0.05 + rng.uniform(0, 0.05), z + rng.uniform(-0.3, 0.3))
            if oid not in self._taken:
                break
        self._taken.add(oid)
        self.facts["objects"][oid] = {"type": obj_type, "props": props, "location": "loc|0|0|0|30"}
        if recep is not None:
            self.facts["in_receptacle"].append([oid, recep])
        return oid

    def can_hold(self, recep: str, obj_type: str) -> bool:
        allowed = type_facts()["receptacle_objects"]
        rtype = self.facts["receptacles"][recep]["type"] if recep in self.facts["receptacles"] else self.facts["objects"][recep]["type"]
        return obj_type in allowed.get(rtype, ())


def _ring(n: int, rng: random.Random) -> list[tuple[float, float]]:
    """n station centres on a rectangle, at least 3.2 m apart (beyond twice the visibility distance)."""
    step = 3.4
    perimeter = n * step
    w = perimeter / 4 + rng.uniform(0.0, 1.0)
    h = perimeter / 2 - w
    out = []
    for k in range(n):
        d = k * step + rng.uniform(-0.1, 0.1)
        d %= 2 * (w + h)
        if d < w:
            out.append((d, 0.0))
        elif d < w + h:
            out.append((w, d - w))
        elif d < 2 * w + h:
            out.append((2 * w + h - d, h))
        else:
            out.append((0.0, 2 * (w + h) - d))
    return [(x - w / 2, z - h / 2) for x, z in out]


def build_room(kind: str, rng: random.Random, *, want_lamp: bool) -> Room:
    spec = ROOMS[kind]
    stations = [st for st in spec["stations"] if any(rng.randint(*c) for _, c in st)]
    centres = _ring(len(stations) + 1, rng)  # the last centre is where the agent starts
    room = Room(kind, {"floor_plan": f"Generated{kind}", "receptacles": {}, "objects": {}, "in_receptacle": [],
                       "other_facts": {}, "in_receptacle_derived": []})
    for s, (station, (cx, cz)) in enumerate(zip(stations, centres, strict=False)):
        for rtype, (lo, hi) in station:
            for k in range(rng.randint(lo, hi)):
                angle = rng.uniform(0, 2 * math.pi)
                rad = 0.0 if k == 0 and rtype == station[0][0] else rng.uniform(0.25, 0.6)
                x, z, y = cx + rad * math.cos(angle), cz + rad * math.sin(angle), _HEIGHT[rtype]
                suffix = rtype if rtype in ("SinkBasin", "BathtubBasin") else ""
                base = {"SinkBasin": "Sink", "BathtubBasin": "Bathtub"}.get(rtype, rtype)
                rid = fmt_id(base, x, y, z, suffix)
                room.facts["receptacles"][rid] = {"type": rtype, "openable": rtype in _OPENABLE, "location": "loc|0|0|0|30"}
                room.receptacles.append(rid)
                room.station_of[rid] = s
                if suffix:  # the fixture around the basin, and the faucet above a sink
                    room.facts["objects"][fmt_id(base, x, y - 0.05, z)] = {"type": base, "props": [], "location": "loc"}
                if rtype == "SinkBasin":
                    room.facts["objects"][fmt_id("Faucet", x, y + 0.3, z - 0.25)] = {"type": "Faucet", "props": [], "location": "loc"}
    if want_lamp and kind in _LAMPS:
        lamp, beside = _LAMPS[kind]
        near = next((r for r in room.receptacles if room.facts["receptacles"][r]["type"] == beside), room.receptacles[0])
        x, _, z = (float(v) for v in near.split("|")[1:4])
        room.facts["objects"][fmt_id(lamp, x + 0.3, 0.8, z + 0.2)] = {"type": lamp, "props": ["toggleable"], "location": "loc"}
    room.agent = centres[-1]
    return room
