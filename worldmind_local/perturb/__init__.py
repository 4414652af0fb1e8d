"""The paper's stress tests as run options (recorded in the stream identity, see runner/config.py):

- `rename`: object names in env feedback and observation text replaced by synonyms (`rename.py`);
- `poison:RATE`: a share of the initial repository replaced by wrong rules at load time (`poison.py`);
- task order: a stream's episodes in a seeded permutation (`order.py`).

Imports stay light: `datasets` is imported only when a memory is actually poisoned.
"""

from __future__ import annotations

from typing import Any

from worldmind_local.perturb.order import permute, task_order
from worldmind_local.perturb.poison import parse_perturb, poison_memory, poison_rate, with_poison
from worldmind_local.perturb.rename import RenamedAdapter, Renamer, rename_table

__all__ = ["permute", "task_order", "parse_perturb", "poison_memory", "poison_rate", "with_poison",
           "RenamedAdapter", "Renamer", "rename_table", "perturbed_adapter"]


def perturbed_adapter(adapter: Any, perturb: str | None) -> Any:
    """The adapter a stream runs with: renaming envs for `rename`, the adapter itself otherwise."""
    return RenamedAdapter(adapter) if parse_perturb(perturb) == "rename" else adapter
