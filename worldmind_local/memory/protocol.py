"""The `Memory` protocol: what the runner needs of any method's global memory.

The World Knowledge Repository implements it, and so does every baseline's store. The runner is the
only writer: after an episode it embeds the entries the method produced (`embed`), adds them in order
(`add_embedded`, which applies the memory's own admission rules: dedup, budget), marks the commit
(`commit(episode)`), and saves the memory atomically as a Hugging Face dataset (`save`). A resumed
stream re-opens the saved memory and cuts it back to the last recorded episode (`commits`,
`truncated`); waves run on `copy()` snapshots. Methods only read a memory, through their own
retrieval calls.
"""

from __future__ import annotations

import os
from typing import Any, Protocol, runtime_checkable

__all__ = ["Memory"]


@runtime_checkable
class Memory(Protocol):
    commits: list[list[int]]      # [episode index, rows after its commit] per committed episode

    async def embed(self, entries: list[Any]) -> list[Any]: ...

    def add_embedded(self, entry: Any) -> bool: ...

    def commit(self, episode: int) -> None: ...

    def truncated(self, rows: int) -> Memory: ...

    def copy(self) -> Memory: ...

    def save(self, path: str | os.PathLike[str]) -> None: ...

    def entries(self) -> list[Any]: ...

    def entry_from_record(self, item: dict[str, Any]) -> Any: ...

    def __len__(self) -> int: ...
