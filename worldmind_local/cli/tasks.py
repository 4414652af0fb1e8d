"""`worldmind tasks list|show`: inspect a suite's tasks, their expert plans and action spaces."""

from __future__ import annotations

import argparse
import functools
import json
import os
import sys
from collections.abc import Callable
from typing import Any

from worldmind_local.cli.replay import add_suite_arguments, suite_from_args

__all__ = ["register"]


def register(subparsers: Any) -> None:
    p = subparsers.add_parser("tasks", help="list tasks or show one task", description=__doc__)
    sub = p.add_subparsers(dest="tasks_command", metavar="{list,show}", required=True)
    ls = sub.add_parser("list", help="one line per task: subset, index, type, instruction")
    add_suite_arguments(ls)
    ls.add_argument("--subset", help="only this subset (default: all)")
    ls.set_defaults(func=run_list)
    show = sub.add_parser("show", help="a task's instruction, type, expert plan and action space")
    add_suite_arguments(show)
    show.add_argument("--subset", required=True)
    show.add_argument("--index", type=int, required=True)
    show.add_argument("--actions", action="store_true", help="print the full action space with ids")
    show.add_argument("--env", default="twin", help="env whose action space is shown (default twin)")
    show.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    show.set_defaults(func=run_show)


def _subsets(args: argparse.Namespace) -> list[str]:
    from worldmind_local.data import adapter

    known = list(adapter(args.benchmark).subsets)
    if args.subset and args.subset not in known:
        raise ValueError(f"unknown subset {args.subset!r} for {args.benchmark}; known: {', '.join(known)}")
    return [args.subset] if args.subset else known


def _pipe_safe(fn: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """Let `worldmind tasks ... | head` end quietly when the reader closes the pipe."""

    @functools.wraps(fn)
    def wrapper(args: argparse.Namespace) -> int:
        try:
            rc = fn(args)
            sys.stdout.flush()
            return rc
        except BrokenPipeError:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 0

    return wrapper


@_pipe_safe
def run_list(args: argparse.Namespace) -> int:
    suite = suite_from_args(args)
    print(f"# {suite.describe()}")
    for subset in _subsets(args):
        for task in suite.tasks(subset):
            print(f"{subset}\t{task.index}\t{task.task_type}\t{task.instruction}")
    return 0


@_pipe_safe
def run_show(args: argparse.Namespace) -> int:
    from worldmind_local.data import adapter

    suite = suite_from_args(args)
    tasks = suite.tasks(_subsets(args)[0])
    if not 0 <= args.index < len(tasks):
        raise ValueError(f"index {args.index} out of range 0..{len(tasks) - 1} for subset {args.subset!r}")
    task = tasks[args.index]
    env = adapter(args.benchmark).make_env(args.env)
    try:
        observation = env.reset(task)
        actions = list(env.actions)
        state_text = observation.text
    except ImportError as exc:  # an optional env (e.g. --env embodiedbench) is not installed
        print(f"worldmind tasks: error: {exc}", file=sys.stderr)
        return 2
    finally:
        env.close()
    record = {
        "id": task.id, "benchmark": task.benchmark, "subset": task.subset, "index": task.index,
        "task_type": task.task_type, "instruction": task.instruction,
        "expert_plan": list(task.expert_plan or ()), "n_actions": len(actions), "initial_state": state_text,
    }
    if args.actions:
        record["actions"] = actions
    if args.json:
        print(json.dumps(record, indent=1))
        return 0
    print(f"{task.id}  [{task.task_type}]\n{task.instruction}\n")
    print(f"initial state: {state_text}\n")
    plan = task.expert_plan or ()
    print(f"expert plan ({len(plan)} actions):" if plan else "expert plan: none")
    for k, name in enumerate(plan, start=1):
        print(f"  {k:2d}. [{actions.index(name) if name in actions else '?'}] {name}")
    print(f"\naction space: {len(actions)} actions" + ("" if args.actions else " (--actions lists them)"))
    if args.actions:
        for k, name in enumerate(actions):
            print(f"  {k:4d}  {name}")
    return 0
