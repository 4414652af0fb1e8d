"""The observation text: frustum, distance and bearing words, grouping of instances."""

from __future__ import annotations

from benchmarks.eb_navigation.observe import Pose, describe, visible_objects


def _obj(obj_type: str, x: float, y: float, z: float) -> tuple[str, str, float, float, float]:
    return (f"{obj_type}|{x}|{y}|{z}", obj_type, x, y, z)


def test_field_of_view_and_bearing() -> None:
    pose = Pose(0.0, 0.9, 0.0, 0.0, 0.0)  # facing +z
    objects = [
        _obj("Ahead", 0.0, 1.0, 2.0),
        _obj("SlightRight", 0.7, 1.0, 2.0),  # ~19 degrees right
        _obj("WellLeft", -1.5, 1.0, 2.0),  # ~37 degrees left
        _obj("Outside", 3.0, 1.0, 2.0),  # ~56 degrees: outside the 100-degree view
        _obj("Behind", 0.0, 1.0, -2.0),
        _obj("TooFar", 0.0, 1.0, 10.5),
    ]
    seen = visible_objects(pose, objects)
    assert [s.type for s in seen] == ["Ahead", "SlightRight", "WellLeft"]
    text = describe(seen, 0.0)
    assert text.splitlines() == [
        "Objects in view (nearest first):",
        "- Ahead: about 2.0 m ahead",
        "- SlightRight: about 2.0 m ahead, slightly to the right",
        "- WellLeft: about 2.5 m ahead, well to the left",
        "Camera: level.",
    ]


def test_rotation_changes_what_is_ahead() -> None:
    objects = [_obj("Box", 2.0, 1.0, 0.0)]  # on +x
    assert visible_objects(Pose(0.0, 0.9, 0.0, 0.0, 0.0), objects) == []
    seen = visible_objects(Pose(0.0, 0.9, 0.0, 90.0, 0.0), objects)
    assert len(seen) == 1 and abs(seen[0].bearing) < 1e-9


def test_a_floor_object_close_by_needs_the_camera_tilted_down() -> None:
    can = [_obj("GarbageCan", 0.0, 0.0, 1.0)]  # 1 m ahead on the floor: ~57 degrees below eye level
    assert visible_objects(Pose(0.0, 0.9, 0.0, 0.0, 0.0), can) == []
    assert visible_objects(Pose(0.0, 0.9, 0.0, 0.0, 30.0), can)
    assert visible_objects(Pose(0.0, 0.9, 0.0, 0.0, -30.0), can) == []


def test_instances_of_a_type_share_a_line() -> None:
    pose = Pose(0.0, 0.9, 0.0, 0.0, 0.0)
    objects = [_obj("Cabinet", 0.0, 0.5, 3.0), _obj("Cabinet", 0.0, 0.5, 1.6), _obj("Bread", 0.2, 0.9, 2.2)]
    text = describe(visible_objects(pose, objects), 30.0, blocked_ahead="CounterTop")
    assert text.splitlines() == [
        "Objects in view (nearest first):",
        "- Cabinet (2 in view, nearest): about 1.5 m ahead",
        "- Bread: about 2.0 m ahead",
        "Right in front (within 0.25 m): CounterTop; moving forward is blocked.",
        "Camera: tilted 30 degrees down.",
    ]


def test_nothing_in_view() -> None:
    assert describe([], -30.0) == "No known objects are in view.\nCamera: tilted 30 degrees up."
