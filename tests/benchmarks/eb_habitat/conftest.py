"""A small hand-built EB-Habitat episode (no data pack needed) and a task factory."""

from __future__ import annotations

import copy
import json
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from worldmind_local.env import Task

R = "receptacle_aabb_"
TABLE_1 = R + "Tbl1_Top1_frl_apartment_table_01"
TABLE_2 = R + "Tbl2_Top1_frl_apartment_table_02"
SINK = R + "sink_kitchen_counter"
COUNTER_LEFT = R + "counter_left_kitchen_counter"
COUNTER_RIGHT = R + "counter_right_kitchen_counter"
SOFA = R + "Sofa_frl_apartment_sofa"
FRIDGE = R + "middle_topfrl_apartment_refrigerator"
DRAWER_LEFT = R + "drawer_left_top_frl_apartment_kitchen_counter"
SUBSETS = (
    "base",
    "common_sense",
    "complex_instruction",
    "spatial_relationship",
    "visual_appearance",
    "long_horizon",
)


def _obj(asset: str, n: int, category: str, recep: str) -> dict[str, Any]:
    return {
        "asset": f"{asset}.object_config.json",
        "category": category,
        "position": [0.0, 0.0, 0.0],
        "transform": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
        "instance_name": f"{asset}_:{n:04d}",
        "start_receptacle": recep,
    }


APPLE_T1, APPLE_SINK, CUP, KNIFE, BOWL = (
    "013_apple_:0000",
    "013_apple_:0001",
    "025_mug_:0000",
    "032_knife_:0000",
    "024_bowl_:0000",
)


@pytest.fixture
def names() -> SimpleNamespace:
    """Entity names of the hand-built episode."""
    return SimpleNamespace(
        APPLE_T1=APPLE_T1,
        APPLE_SINK=APPLE_SINK,
        CUP=CUP,
        KNIFE=KNIFE,
        BOWL=BOWL,
        TABLE_1=TABLE_1,
        TABLE_2=TABLE_2,
        SINK=SINK,
        SOFA=SOFA,
        FRIDGE=FRIDGE,
        COUNTER_LEFT=COUNTER_LEFT,
        COUNTER_RIGHT=COUNTER_RIGHT,
        DRAWER_LEFT=DRAWER_LEFT,
        SUBSETS=SUBSETS,
    )


@pytest.fixture
def episode() -> dict[str, Any]:
    """Apples on table 1 and the sink, a mug on the left counter, a knife in the (closed) fridge, a bowl
    in the left drawer. Goal: some apple on the sofa, hand empty."""
    objs = [
        _obj("013_apple", 0, "apple", TABLE_1),
        _obj("013_apple", 1, "apple", SINK),
        _obj("025_mug", 0, "mug", COUNTER_LEFT),
        _obj("032_knife", 0, "knife", FRIDGE),
        _obj("024_bowl", 0, "bowl", DRAWER_LEFT),
    ]
    return {
        "index": 0,
        "loaded_episode_id": "0",
        "episode_id": "t0",
        "scene_id": "test",
        "instruction": "Put an apple on the sofa.",
        "instruct_id": "test",
        "sampled_entities": {},
        "start_preds": [],
        "goal_preds": {
            "expr_type": "AND",
            "quantifier": "EXISTS",
            "inputs": [{"name": "X", "expr_type": "apple"}],
            "sub_exprs": [f"on_top(X, {SOFA})", "not_holding()"],
        },
        "subgoals": [
            [f"robot_at({TABLE_1})", f"robot_at({APPLE_T1})"],
            [f"holding({APPLE_T1})", f"robot_at({TABLE_1})"],
            [f"on_top({APPLE_T1},{SOFA})", f"holding({APPLE_T1})", f"robot_at({SOFA})"],
            [f"on_top({APPLE_T1},{SOFA})", f"robot_at({SOFA})"],
        ],
        "name_to_receptacle": {o["instance_name"]: o["start_receptacle"] for o in objs},
        "rigid_objs": objs,
        "markers": [],
        "ao_states": {"fridge_:0000": {"2": 0.0}},
        "start_position": [0, 0, 0],
        "start_rotation": [0, 0, 0, 1],
        "targets": {},
        "target_receptacles": [],
        "goal_receptacles": [],
        "info": {},
        "sampler_info": {},
    }


@pytest.fixture
def make_task() -> Callable[..., Task]:
    def make(episode: dict[str, Any], **changes: Any) -> Task:
        record = copy.deepcopy(episode)
        record.update(changes)
        return Task(
            f"test/{record['index']}",
            "eb_habitat",
            "base",
            record["index"],
            record["instruction"],
            "test",
            payload=record,
        )

    return make


@pytest.fixture
def write_subset(tmp_path: Path) -> Callable[[str, Any], Path]:
    """Write `content` as data_dir/eb_habitat/<subset>.json; returns data_dir."""

    def write(subset: str, content: Any) -> Path:
        folder = tmp_path / "eb_habitat"
        folder.mkdir(exist_ok=True)
        text = content if isinstance(content, str) else json.dumps(content)
        (folder / f"{subset}.json").write_text(text, encoding="utf-8")
        return tmp_path

    return write
