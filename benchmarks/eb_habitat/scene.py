"""Static facts of EB-Habitat's ReplicaCAD apartment: receptacles, markers, categories, and reach.

Every EB-Habitat episode uses the same apartment (`v3_sc*_staging_*`), so these facts are shared by
the twin, the oracle and the generator. Names are EmbodiedBench's entity names, verbatim.

The spatial model (documented here because every other module leans on it)
---------------------------------------------------------------------------
EmbodiedBench decides `robot_at(Y)` geometrically: the robot base is within 2 m (xz) of Y's position.
`nav(Y)` teleports the robot to the navigable point closest to Y, so after a navigation several
receptacles can count as "at" the robot at once (the kitchen receptacles sit side by side). The twin
replaces the geometry by two tables keyed by the robot's *place* (the last navigation target):

* ``REACH[place]`` - the static entities for which `robot_at` holds at that place (``episode_reach``
  widens it per episode by what that episode's own snapshots recorded, since the furniture and the
  robot's stopping points differ between scene variants). It is the majority rule over the
  episodes' recorded subgoal states: each subgoal is a snapshot of the predicates
  that held after an expert step, and ``derive_reach_table`` attributes every snapshot to the place
  the expert was at and keeps the entities present in at least half of that place's snapshots.
  Places no expert navigates to (the cabinet push points, the two drawers, the refrigerator itself)
  use the set seen in the snapshots where all four cabinet push points (resp. the refrigerator push
  point) were within reach.
* ``HOME[place]`` - the receptacles the robot actually stands at: the target itself plus, for a
  marker, the receptacle the marker opens (fridge_push_point -> refrigerator shelf, cab_push_point_7
  -> left drawer, cab_push_point_5 -> right drawer; the mapping of EmbodiedBench's drawer markers).

How objects relate to places: an object rests on one receptacle (`name_to_receptacle` /
`rigid_objs[*].start_receptacle` at reset, then wherever it was placed). It is "near the robot"
(`robot_at(obj)`, `robot_at_obj(obj)`, the pick precondition) when it is held, when its receptacle is
in the place's reach, or when the episode's recordings list it near that place and it has not moved
from where it started; a pick prefers objects on ``HOME[place]``. An object on a receptacle inside the
refrigerator or a drawer is out of reach while that door is closed. A held object counts as
`on_top` of the ``HOME`` receptacles (EmbodiedBench's on_top test is geometric and the gripper
holds the object over the receptacle the robot faces; the recorded subgoals contain exactly such
holding-and-on_top states).
"""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

__all__ = [
    "CAB_MARKERS",
    "FRIDGE_MARKER",
    "MARKERS",
    "RECEPTACLES",
    "OPEN_AIR_RECEPTACLES",
    "STATIC_ENTITIES",
    "CATEGORIES",
    "CATEGORY_ASSETS",
    "MARKER_RECEPTACLE",
    "CONTAINER_OF",
    "REACH",
    "HOME",
    "RECEPTACLE_TEXT",
    "RECEPTACLE_LOOKS",
    "NOMINAL_POSITION",
    "MARKER_RECORDS",
    "attributed_snapshots",
    "derive_reach_table",
    "episode_reach",
]

CAB_MARKERS: tuple[str, ...] = (
    "cab_push_point_7",
    "cab_push_point_6",
    "cab_push_point_5",
    "cab_push_point_4",
)
FRIDGE_MARKER = "fridge_push_point"
MARKERS: tuple[str, ...] = (*CAB_MARKERS, FRIDGE_MARKER)

_R = "receptacle_aabb_"
CHAIR = _R + "Chr1_Top1_frl_apartment_chair_01"
TABLE_1 = _R + "Tbl1_Top1_frl_apartment_table_01"
TABLE_2 = _R + "Tbl2_Top1_frl_apartment_table_02"
TV_STAND = _R + "TvStnd1_Top1_frl_apartment_tvstand"
SINK = _R + "sink_kitchen_counter"
COUNTER_RIGHT = _R + "counter_right_kitchen_counter"
COUNTER_LEFT = _R + "counter_left_kitchen_counter"
SOFA = _R + "Sofa_frl_apartment_sofa"
FRIDGE = _R + "middle_topfrl_apartment_refrigerator"
DRAWER_LEFT = _R + "drawer_left_top_frl_apartment_kitchen_counter"
DRAWER_RIGHT = _R + "drawer_right_top_frl_apartment_kitchen_counter"

# In EmbodiedBench's skill order (nav 5..15, place 49..59).
RECEPTACLES: tuple[str, ...] = (
    CHAIR,
    TABLE_1,
    TABLE_2,
    TV_STAND,
    SINK,
    COUNTER_RIGHT,
    COUNTER_LEFT,
    SOFA,
    FRIDGE,
    DRAWER_LEFT,
    DRAWER_RIGHT,
)
# Where episodes place objects at the start and name goals (dataset.yaml's "open_air_receps").
OPEN_AIR_RECEPTACLES: tuple[str, ...] = (TABLE_1, TABLE_2, TV_STAND, SINK, COUNTER_RIGHT, COUNTER_LEFT, SOFA)
# Navigation targets in skill order: the index of an entity here is its nav skill id.
STATIC_ENTITIES: tuple[str, ...] = (*MARKERS, *RECEPTACLES)

# The 33 object categories in EmbodiedBench's pick-skill order (dataset.yaml "all_cats").
CATEGORIES: tuple[str, ...] = (
    "ball",
    "clamp",
    "hammer",
    "screwdriver",
    "padlock",
    "scissors",
    "block",
    "drill",
    "spatula",
    "knife",
    "spoon",
    "plate",
    "sponge",
    "cleanser",
    "plum",
    "pear",
    "peach",
    "apple",
    "lemon",
    "can",
    "box",
    "banana",
    "strawberry",
    "lego",
    "rubriks cube",
    "book",
    "bowl",
    "cup",
    "mug",
    "orange",
    "lid",
    "toy airplane",
    "wrench",
)

# dataset.yaml object_sets: the assets that make up each category (a test checks this against the file).
CATEGORY_ASSETS: dict[str, tuple[str, ...]] = {
    "ball": ("053_mini_soccer_ball", "054_softball", "055_baseball", "056_tennis_ball", "057_racquetball"),
    "clamp": ("050_medium_clamp", "051_large_clamp", "052_extra_large_clamp"),
    "hammer": ("048_hammer",),
    "screwdriver": ("043_phillips_screwdriver", "044_flat_screwdriver"),
    "wrench": ("042_adjustable_wrench",),
    "padlock": ("038_padlock",),
    "scissors": ("037_scissors",),
    "block": ("036_wood_block", "070-a_colored_wood_blocks", "070-b_colored_wood_blocks"),
    "drill": ("035_power_drill",),
    "spatula": ("033_spatula",),
    "knife": ("032_knife",),
    "spoon": ("031_spoon",),
    "plate": ("029_plate",),
    "lid": ("028_skillet_lid",),
    "sponge": ("026_sponge",),
    "cleanser": ("021_bleach_cleanser",),
    "plum": ("018_plum",),
    "orange": ("017_orange",),
    "pear": ("016_pear",),
    "peach": ("015_peach",),
    "apple": ("013_apple",),
    "lemon": ("014_lemon",),
    "can": ("002_master_chef_can", "005_tomato_soup_can", "007_tuna_fish_can", "010_potted_meat_can"),
    "box": ("003_cracker_box", "004_sugar_box", "008_pudding_box", "009_gelatin_box"),
    "banana": ("011_banana",),
    "strawberry": ("012_strawberry",),
    "toy airplane": tuple(f"072-{c}_toy_airplane" for c in "abcde"),
    "lego": tuple(f"073-{c}_lego_duplo" for c in "abcdefg"),
    "rubriks cube": ("077_rubiks_cube",),
    "book": tuple(f"frl_apartment_book_0{i}" for i in (1, 2, 3, 4, 5, 6)),
    "bowl": (*(f"frl_apartment_bowl_0{i}" for i in (1, 2, 3, 6, 7)), "024_bowl"),
    "mug": ("025_mug",),
    "cup": (*(f"065-{c}_cups" for c in "abcdefghij"), *(f"frl_apartment_cup_0{i}" for i in (1, 2, 3, 5))),
}

# The receptacle each door marker opens; markers without one (cabinets 6 and 4) hold nothing we model.
MARKER_RECEPTACLE: dict[str, str] = {
    FRIDGE_MARKER: FRIDGE,
    "cab_push_point_7": DRAWER_LEFT,
    "cab_push_point_5": DRAWER_RIGHT,
}
CONTAINER_OF: dict[str, str] = {recep: marker for marker, recep in MARKER_RECEPTACLE.items()}

_KITCHEN_DRAWERS = frozenset({*CAB_MARKERS, DRAWER_LEFT, DRAWER_RIGHT, SINK, COUNTER_RIGHT})
_FRIDGE_FRONT = frozenset({FRIDGE_MARKER, FRIDGE, COUNTER_LEFT, DRAWER_LEFT})

REACH: dict[str, frozenset[str]] = {
    **{marker: _KITCHEN_DRAWERS for marker in CAB_MARKERS},
    FRIDGE_MARKER: _FRIDGE_FRONT,
    CHAIR: frozenset({CHAIR}),
    TABLE_1: frozenset({TABLE_1}),
    TABLE_2: frozenset({TABLE_2}),
    TV_STAND: frozenset({TV_STAND}),
    SINK: frozenset({SINK, COUNTER_LEFT, COUNTER_RIGHT, DRAWER_LEFT, DRAWER_RIGHT}),
    COUNTER_RIGHT: frozenset({COUNTER_RIGHT, SINK, DRAWER_LEFT, DRAWER_RIGHT}),
    COUNTER_LEFT: frozenset({COUNTER_LEFT, SINK, DRAWER_LEFT, FRIDGE}),
    SOFA: frozenset({SOFA}),
    FRIDGE: _FRIDGE_FRONT,
    DRAWER_LEFT: _KITCHEN_DRAWERS,
    DRAWER_RIGHT: _KITCHEN_DRAWERS,
}

HOME: dict[str, frozenset[str]] = {
    name: frozenset({name, MARKER_RECEPTACLE[name]}) if name in MARKER_RECEPTACLE else frozenset({name})
    for name in STATIC_ENTITIES
}

# How EmbodiedBench's skill texts name each entity ("navigate to the <text>").
RECEPTACLE_TEXT: dict[str, str] = {
    **{marker: f"cabinet {marker.rsplit('_', 1)[1]}" for marker in CAB_MARKERS},
    FRIDGE_MARKER: "refrigerator push point",
    CHAIR: "chair 1",
    TABLE_1: "table 1",
    TABLE_2: "table 2",
    TV_STAND: "TV stand",
    SINK: "sink in the kitchen",
    COUNTER_RIGHT: "right counter in the kitchen",
    COUNTER_LEFT: "left counter in the kitchen",
    SOFA: "sofa",
    FRIDGE: "refrigerator",
    DRAWER_LEFT: "left drawer of the kitchen counter",
    DRAWER_RIGHT: "right drawer of the kitchen counter",
}

# Everyday names instructions use (instructions.yaml name_mappings), for the generator.
RECEPTACLE_LOOKS: dict[str, str] = {
    CHAIR: "chair",
    TABLE_1: "black table",
    TABLE_2: "brown table",
    TV_STAND: "TV stand",
    SINK: "sink",
    COUNTER_RIGHT: "right counter",
    COUNTER_LEFT: "left counter",
    SOFA: "sofa",
    FRIDGE: "fridge",
    DRAWER_LEFT: "left drawer",
    DRAWER_RIGHT: "right drawer",
}

# Median start position of the objects on each receptacle over the 300 episodes (x, y, z); the four
# receptacles no episode starts an object on are placed by the layout (fridge beside the left
# counter, drawers under the counter). Generated records use these; the twin never reads positions.
NOMINAL_POSITION: dict[str, tuple[float, float, float]] = {
    CHAIR: (2.2, 0.5, 4.2),
    TABLE_1: (2.46, 0.79, 5.01),
    TABLE_2: (1.53, 0.96, 2.29),
    TV_STAND: (0.83, 0.65, 5.3),
    SINK: (-2.14, 0.73, 1.98),
    COUNTER_RIGHT: (-2.13, 0.89, 1.04),
    COUNTER_LEFT: (-2.12, 0.89, 2.77),
    SOFA: (3.11, 0.43, 5.35),
    FRIDGE: (-2.1, 1.1, 3.6),
    DRAWER_LEFT: (-2.0, 0.6, 2.3),
    DRAWER_RIGHT: (-2.0, 0.6, 1.6),
}

# The markers every episode carries (identical across the 300 episodes).
MARKER_RECORDS: tuple[dict[str, Any], ...] = (
    *(
        {
            "name": m,
            "type": "articulated_object",
            "offset": [0.3, 0.0, 0.0],
            "link": link,
            "object": "kitchen_counter_:0000",
        }
        for m, link in zip(CAB_MARKERS, ("drawer1_top", "drawer2_top", "drawer3", "drawer4"), strict=True)
    ),
    {
        "name": FRIDGE_MARKER,
        "type": "articulated_object",
        "offset": [0.1, -0.62, 0.2],
        "link": "top_door",
        "object": "fridge_:0000",
    },
)


def attributed_snapshots(episode: Mapping[str, Any]) -> Iterator[tuple[str, frozenset[str], frozenset[str]]]:
    """(place, static entities, objects) recorded within reach, for each subgoal snapshot of an episode.

    A snapshot is attributed to a place by the step that produced it: a new `holding(o)` happened at
    o's receptacle (or at R when the same snapshot has `on_top(o, R)`: the robot already carried o to
    R), a new `on_top(o, R)` at R, a new `closed_fridge` at the fridge push point. Snapshots with no
    such change or no `robot_at` at all are skipped. The recorded lists are partial (EmbodiedBench
    kept a selection of the true predicates), so an entity's absence proves nothing.
    """
    where = {o["instance_name"]: o["start_receptacle"] for o in episode["rigid_objs"]}
    before: set[str] = set()
    for snapshot in episode.get("subgoals") or []:
        place = _attribute(snapshot, before, where)
        before = set(snapshot)
        near = [p[p.index("(") + 1 : -1] for p in snapshot if p.startswith(("robot_at(", "robot_at_obj("))]
        statics = frozenset(e for e in near if e in REACH)
        if place is not None and near:
            yield place, statics, frozenset(e for e in near if e not in REACH)


def derive_reach_table(
    episodes: Iterable[Mapping[str, Any]], *, quorum: float = 0.5
) -> dict[str, frozenset[str]]:
    """Re-derive ``REACH`` from recorded subgoal snapshots (the provenance of the table above): the
    static entities present in at least `quorum` of the snapshots attributed to a place."""
    seen: dict[str, Counter[str]] = defaultdict(Counter)
    count: Counter[str] = Counter()
    for episode in episodes:
        for place, statics, _ in attributed_snapshots(episode):
            if statics:
                count[place] += 1
                seen[place].update(statics)
    return {
        place: frozenset(e for e, n in seen[place].items() if n >= quorum * count[place]) for place in count
    }


def episode_reach(
    episode: Mapping[str, Any],
) -> tuple[dict[str, frozenset[str]], dict[str, frozenset[str]]]:
    """``REACH`` widened for one episode by its own recordings, and the objects recorded near each place.

    The furniture and the robot's stopping points differ between ReplicaCAD scene variants, and the
    episode's subgoal snapshots were recorded in its own scene: an entity they list as within reach
    of a place is within reach there in this episode, on top of the majority table. Objects they list
    near a place count as near it while they lie where they started (positions come from the start).
    """
    table = {place: set(near) for place, near in REACH.items()}
    objects: dict[str, set[str]] = defaultdict(set)
    for place, statics, objs in attributed_snapshots(episode):
        table[place] |= statics
        objects[place] |= objs
    return {p: frozenset(v) for p, v in table.items()}, {p: frozenset(v) for p, v in objects.items()}


def _attribute(snapshot: list[str], before: set[str], where: dict[str, str]) -> str | None:
    place = None
    for pred in snapshot:
        if pred in before:
            continue
        if pred.startswith("holding("):
            obj = pred[8:-1]
            carried = [p for p in snapshot if p.startswith(f"on_top({obj},")]
            place = carried[0][len(obj) + 8 : -1] if carried else where.get(obj)
        elif pred.startswith("on_top("):
            obj, recep = pred[7:-1].split(",")
            place = recep
            if f"holding({obj})" not in snapshot:
                where[obj] = recep
        elif pred == f"closed_fridge({FRIDGE_MARKER})":
            place = FRIDGE_MARKER
    return place
