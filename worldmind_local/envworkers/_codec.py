"""What crosses the worker boundary: plain data, never simulator objects.

An observation crosses field by field (`text`, `state`, `image`), each only once somebody has read it
(or it was asked for eagerly), so the twins' lazy text and picture stay lazy. An image crosses as a
uint8 array plus its mode (a pipe copies it once; Ray's object store shares it without a copy) or,
for modes an array cannot carry and on request, as PNG bytes (lossless; smaller across nodes).
A step's `info` crosses only as far as it pickles: anything else is replaced by its repr.
"""

from __future__ import annotations

import io
import pickle
from typing import Any

import numpy as np

__all__ = ["FIELDS", "encode_field", "decode_field", "encode_step", "step_digest", "picklable_info"]

FIELDS = ("text", "state", "image")
_ARRAY_MODES = ("RGB", "RGBA", "L")


def encode_image(image: Any, codec: str = "array") -> tuple[Any, ...] | None:
    """A PIL image (or an array, as some simulators hand out) as plain data."""
    if image is None:
        return None
    if isinstance(image, np.ndarray):
        return ("ndarray", np.ascontiguousarray(image))
    mode = getattr(image, "mode", None)
    if codec == "array" and mode in _ARRAY_MODES:
        return ("array", mode, np.asarray(image))
    buf = io.BytesIO()
    image.save(buf, format="PNG")
    return ("png", buf.getvalue())


def decode_image(frame: tuple[Any, ...] | None) -> Any:
    if frame is None:
        return None
    kind = frame[0]
    if kind == "ndarray":
        return frame[1]
    from PIL import Image

    if kind == "array":
        image = Image.fromarray(frame[2])
        return image if image.mode == frame[1] else image.convert(frame[1])
    if kind == "png":
        image = Image.open(io.BytesIO(frame[1]))
        image.load()
        return image
    raise ValueError(f"unknown frame encoding {kind!r}")


def encode_field(obs: Any, name: str, codec: str = "array") -> Any:
    if name == "text":
        return obs.text
    if name == "state":
        return obs.state
    if name == "image":
        return encode_image(obs.image, codec)
    raise ValueError(f"unknown observation field {name!r}; fields: {', '.join(FIELDS)}")


def decode_field(name: str, value: Any) -> Any:
    return decode_image(value) if name == "image" else value


def picklable_info(info: dict[str, Any]) -> dict[str, Any]:
    """`StepResult.info` as far as it can cross: unpicklable values (simulator handles) become reprs."""
    try:
        pickle.dumps(info)
        return info
    except Exception:
        out: dict[str, Any] = {}
        for key, value in info.items():
            try:
                pickle.dumps(value)
                out[str(key)] = value
            except Exception:
                out[str(key)] = repr(value)
        return out


def encode_step(result: Any) -> dict[str, Any]:
    """A StepResult without its observation (that travels separately, by field)."""
    return {
        "feedback": result.feedback, "success": result.success, "progress": result.progress,
        "invalid": result.invalid, "done": result.done, "end_reason": result.end_reason,
        "info": picklable_info(result.info),
    }


def step_digest(step: dict[str, Any]) -> tuple[Any, ...]:
    """What a replayed step must reproduce exactly for the episode to go on after a restart."""
    return (step["feedback"], step["success"], step["progress"], step["invalid"], step["done"],
            step["end_reason"])
