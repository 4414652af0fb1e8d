from __future__ import annotations

import asyncio
import json

from models.base import ChatRequest
from models.random_backend import RandomBackend

SCHEMA = {
    "type": "object",
    "properties": {
        "verdict": {"type": "string", "enum": ["match", "mismatch"]},
        "ids": {"type": "array", "items": {"type": "integer", "minimum": 0, "maximum": 9}, "minItems": 1},
    },
    "required": ["verdict", "ids"],
}


def test_same_request_same_answer_and_schema_valid():
    b = RandomBackend()
    req = ChatRequest(messages=[{"role": "user", "content": "hello"}], json_schema=SCHEMA)
    other = ChatRequest(messages=[{"role": "user", "content": "hello!"}], json_schema=SCHEMA)
    r1, r2, r3 = asyncio.run(b.complete([req, req, other]))
    assert r1.text == r2.text
    data = json.loads(r1.text)
    assert data["verdict"] in ("match", "mismatch")
    assert data["ids"] and all(0 <= i <= 9 for i in data["ids"])
    assert RandomBackend().model_id == "seeded-random"
    assert r3.completion_tokens > 0
