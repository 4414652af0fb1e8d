"""The model seam: chat requests, results, and the `ChatBackend` protocol every backend implements.

One request = one conversation (text and images) + sampling + an optional JSON schema for structured
output + the role it plays (planner, judge, reflector, distiller, summarizer). Backends take many
requests at once and are free to batch them; the runner sends everything pending of every stream.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol, runtime_checkable

__all__ = [
    "Role",
    "ROLES",
    "Sampling",
    "ChatRequest",
    "ChatResult",
    "ChatBackend",
    "BackendError",
    "ContextLengthError",
    "ModelNotFoundError",
    "request_key",
]

# A request's role tag says which call of a method it is (for accounting and routing). WorldMind's roles
# come first; baselines add their own (selector, critic, world_model, ...). Any short name is valid.
Role = str
ROLES: tuple[str, ...] = ("planner", "judge", "reflector", "distiller", "summarizer", "refiner")


class BackendError(RuntimeError):
    """A backend could not answer (after its retries). The message says which backend and why."""


class ContextLengthError(BackendError):
    """The prompt (plus max_tokens) does not fit the model's context length."""


class ModelNotFoundError(BackendError, FileNotFoundError):
    """A model spec points at weights that are not on this machine."""


@dataclass(frozen=True, slots=True)
class Sampling:
    temperature: float = 0.0
    max_tokens: int = 512
    top_p: float = 1.0
    n: int = 1
    seed: int | None = 0


@dataclass(frozen=True, slots=True)
class ChatRequest:
    """`messages` follow the OpenAI chat format. Content is a string, or a list of parts
    `{"type": "text", "text": ...}` / `{"type": "image", "image": <PIL.Image>}`."""

    messages: tuple[dict[str, Any], ...] | list[dict[str, Any]]
    sampling: Sampling = field(default_factory=Sampling)
    json_schema: dict[str, Any] | None = None
    role: Role = "planner"
    chat_template_kwargs: dict[str, Any] | None = None


@dataclass(slots=True)
class ChatResult:
    texts: list[str]
    prompt_tokens: int
    completion_tokens: int
    latency_s: float
    cached: bool = False
    model: str = ""

    @property
    def text(self) -> str:
        return self.texts[0] if self.texts else ""


@runtime_checkable
class ChatBackend(Protocol):
    """Answers batches of chat requests. `model_id` names the model for caches and provenance."""

    name: str
    model_id: str

    async def complete(self, requests: list[ChatRequest]) -> list[ChatResult]: ...

    async def aclose(self) -> None: ...


def _jsonable_content(content: Any) -> Any:
    """Messages with images made hashable: an image becomes the sha256 of its PNG-free raw bytes."""
    if isinstance(content, str) or content is None:
        return content
    parts = []
    for part in content:
        if part.get("type") == "image" and not isinstance(part.get("image"), str):
            img = part["image"]
            digest = hashlib.sha256(img.tobytes()).hexdigest()
            parts.append({"type": "image", "sha256": digest, "size": list(img.size), "mode": img.mode})
        else:
            parts.append(part)
    return parts


def request_key(model_id: str, request: ChatRequest) -> str:
    """Cache key: sha256 over (model id, messages, sampling, schema, template kwargs, role-free).

    The role is not part of the key: the same prompt asked as judge or planner is the same call.
    """
    payload = {
        "model": model_id,
        "messages": [
            {**{k: v for k, v in m.items() if k != "content"}, "content": _jsonable_content(m.get("content"))}
            for m in request.messages
        ],
        "sampling": asdict(request.sampling),
        "schema": request.json_schema,
        "template": request.chat_template_kwargs or {},
    }
    blob = json.dumps(payload, sort_keys=True, ensure_ascii=False, default=str).encode()
    return hashlib.sha256(blob).hexdigest()
