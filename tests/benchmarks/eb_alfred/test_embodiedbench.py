"""The real-simulator wrapper, tested against hand-written recordings of EBAlfEnv's outputs.

The recordings follow EmbodiedBench's EBAlfEnv.step contract (obs, reward, done, info with
env_feedback, task_success, task_progress, last_action_success) and its feedback strings; the real
simulator (AI2-THOR 2.1.0) was not run here.
"""

from __future__ import annotations

import importlib.util
from types import SimpleNamespace

import numpy as np
import pytest

from benchmarks.eb_alfred.actions import GLOBAL_ACTIONS
from benchmarks.eb_alfred.embodiedbench import INSTALL_HINT, EmbodiedBenchAlfredEnv, metadata_text
from worldmind_local.env import Task, UnknownActionError

OK = "Last action executed successfully."
METADATA = {
    "objects": [
        {"objectId": "CounterTop|+00.69|+00.95|-02.48", "objectType": "CounterTop", "visible": True,
         "receptacleObjectIds": ["Ladle|-00.79|+01.09|+02.14"]},
        {"objectId": "Ladle|-00.79|+01.09|+02.14", "objectType": "Ladle", "visible": True},
        {"objectId": "Fridge|-03.52|+00.00|+02.72", "objectType": "Fridge", "visible": True, "openable": True, "isOpen": False},
        {"objectId": "Faucet|-01.39|+01.37|+00.17", "objectType": "Faucet", "visible": False, "toggleable": True},
    ],
    "inventoryObjects": [],
}


def info(feedback, success=0.0, progress=0.0, ok=1.0):
    return {"env_feedback": feedback, "task_success": success, "task_progress": progress, "last_action_success": ok,
            "env_step": 0, "object_states": {}}


RECORDING = [
    (False, info(OK)),
    (False, info("Last action is invalid. Robot is currently holding Ladle", ok=0.0)),
    (False, info(OK, progress=0.5)),
    (True, info(OK, success=1.0, progress=1.0)),
]


class FakeEBAlfEnv:
    """Replays RECORDING; exposes the attributes the wrapper reads from EBAlfEnv."""

    def __init__(self, resolution: int) -> None:
        self.language_skill_set = list(GLOBAL_ACTIONS) + ["find a CounterTop_2"]
        self.dataset, self.number_of_episodes, self._current_episode_num = [], 0, 0
        self.id_to_name_dict = {"CounterTop|+00.69|+00.95|-02.48": "CounterTop_2"}
        self.env = SimpleNamespace(last_event=SimpleNamespace(metadata=METADATA), cur_receptacle=None)
        self.steps: list = []
        self.closed = False

    def reset(self):
        assert self.number_of_episodes == 1 and self._current_episode_num == 0
        self.reset_with = self.dataset[0]
        self.steps = list(RECORDING)
        return {"head_rgb": np.zeros((8, 8, 3), dtype=np.uint8)}

    def step(self, action):
        done, inf = self.steps.pop(0)
        self.env.cur_receptacle = "CounterTop|+00.69|+00.95|-02.48"
        return {"head_rgb": np.zeros((8, 8, 3), dtype=np.uint8)}, 0.0, done, inf

    def close(self):
        self.closed = True


def eb_task() -> Task:
    entry = {"task": "pick_clean_then_place_in_recep-Ladle-None-DiningTable-4/trial_T20190909_164840_568811",
             "repeat_idx": 2, "instruction": "Rinse off a ladle and move it to the table."}
    return Task(id="eb_alfred/base/0", benchmark="eb_alfred", subset="base", index=0, instruction=entry["instruction"],
                task_type="pick_clean_then_place_in_recep", payload={"split": entry})


def test_wrapper_translates_recorded_steps():
    fakes = []
    env = EmbodiedBenchAlfredEnv(env_factory=lambda r: fakes.append(FakeEBAlfEnv(r)) or fakes[-1])
    obs = env.reset(eb_task())
    assert fakes[0].reset_with["repeat_idx"] == 2
    assert env.actions[-1] == "find a CounterTop_2" and env.action_id("find a Ladle") == 64
    assert obs.image is not None and obs.image.size == (8, 8)
    assert "CounterTop_2 (contains: Ladle)" in obs.text and "Fridge (closed)" in obs.text and "Faucet" not in obs.text
    first = env.step(env.action_id("find a Ladle"))
    assert first.feedback == OK and not first.invalid and not first.done and first.progress == 0.0
    bad = env.step(env.action_id("pick up the Ladle"))
    assert bad.invalid and bad.feedback.endswith("Robot is currently holding Ladle") and env.invalid == 1
    assert env.step(0).progress == 0.5
    last = env.step(0)
    assert last.success and last.done and last.progress == 1.0 and last.end_reason == "success"
    assert "Location: CounterTop|+00.69|+00.95|-02.48" in last.observation.text
    with pytest.raises(UnknownActionError):
        env.action_id("fly away")
    env.close()
    assert fakes[0].closed


def test_generated_tasks_are_refused():
    env = EmbodiedBenchAlfredEnv(env_factory=FakeEBAlfEnv)
    task = Task(id="gen", benchmark="eb_alfred", subset="base", index=0, instruction="", task_type="x", payload={"key": "g"})
    with pytest.raises(ValueError, match="twin"):
        env.reset(task)


def test_missing_embodiedbench_says_what_to_install():
    if importlib.util.find_spec("embodiedbench") is not None:
        pytest.skip("EmbodiedBench is installed here")
    env = EmbodiedBenchAlfredEnv()
    with pytest.raises(ImportError) as err:
        env.reset(eb_task())
    assert str(err.value) == INSTALL_HINT and "EmbodiedBench" in INSTALL_HINT


def test_metadata_text_holds_the_held_object():
    meta = dict(METADATA, inventoryObjects=[{"objectId": "Ladle|-00.79|+01.09|+02.14", "objectType": "Ladle"}])
    text = metadata_text(meta, {}, "CounterTop")
    assert text.startswith("Location: CounterTop. Holding: Ladle.")
