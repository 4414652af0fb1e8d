"""The action space: EB's 162 global actions and its instance-naming rule."""

from __future__ import annotations

import json

from benchmarks.eb_alfred.actions import GLOBAL_ACTIONS, compile_action, instance_names
from benchmarks.eb_alfred.typefacts import ithor_name, type_facts


def test_global_actions_match_the_data_pack(eb_data_dir):
    pack = json.loads((eb_data_dir / "eb_alfred" / "action_space_global.json").read_text())
    assert list(GLOBAL_ACTIONS) == pack["actions"]
    assert len(GLOBAL_ACTIONS) == 162
    assert type_facts()["global_action_types"] == pack["type_lists"]


def test_type_tables_match_alfred_constants(eb_data_dir):
    constants = json.loads((eb_data_dir / "eb_alfred" / "alfred_constants.json").read_text())
    assert type_facts()["receptacle_objects"] == constants["VAL_RECEPTACLE_OBJECTS"]
    assert type_facts()["action_objects"] == constants["VAL_ACTION_OBJECTS"]


def test_naming_rule():
    receps = [("Cabinet", "Cabinet|1"), ("Drawer", "Drawer|1"), ("Cabinet", "Cabinet|2"), ("Fridge", "Fridge|1")]
    receps += [("Cabinet", f"Cabinet|{k}") for k in range(3, 11)] + [("Bowl", "Bowl|1"), ("Bowl", "Bowl|2")]
    picks = [("Apple", "Apple|1"), ("Apple", "Apple|2"), ("Knife", "Knife|1"), ("Statue", "Statue|1"), ("Statue", "Statue|2")]
    names = instance_names(receps, picks)
    assert names.name_to_id["Cabinet"] == "Cabinet|1" and names.name_to_id["Cabinet_10"] == "Cabinet|10"
    assert "Fridge" not in names.name_to_id and "Knife" not in names.name_to_id
    finds = [a for a in names.extra_actions if a.startswith("find")]
    # receptacle extras sorted as strings (Cabinet_10 before Cabinet_2), then pickupable extras
    assert finds[:3] == ["find a Bowl_2", "find a Cabinet_10", "find a Cabinet_2"]
    assert finds[-2:] == ["find a Apple_2", "find a Statue_2"]
    opens = [a for a in names.extra_actions if not a.startswith("find")]
    assert opens[:2] == ["open the Cabinet_10", "close the Cabinet_10"] and "open the Bowl_2" not in opens
    assert names.actions[:162] == list(GLOBAL_ACTIONS)


def test_compile_substitutes_mapped_names_only_for_find_open_close():
    m = {"Cabinet": "Cabinet|1", "Cabinet_2": "Cabinet|2", "Apple": "Apple|1"}
    assert compile_action("find a Cabinet_2", m) == ("find", "Cabinet|2")
    assert compile_action("open the Cabinet", m) == ("open", "Cabinet|1")
    assert compile_action("pick up the Apple", m) == ("pick", "Apple")
    assert compile_action("put down the object in hand", m) == ("put", "")


def test_ithor_name_quirk():
    assert ithor_name("CounterTop") == "Countertop"
    assert ithor_name("CD") == "CD"
    assert ithor_name("Cabinet|+00.40|+00.40|+00.00") == "Cabinet|+00.40|+00.40|+00.00"
