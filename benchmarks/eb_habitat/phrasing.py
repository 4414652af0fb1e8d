"""Wording for generated EB-Habitat instructions, one table per subset style (our own phrasing).

`{obj}`, `{src}`, `{dst}`, ... are filled by the generator; where a template has no article before
`{obj}`, the generator passes the noun with its article (``a_noun``). Receptacles are named the way people in
the apartment would say it (black table, left counter); the subset styles change how the object or
the receptacle is referred to, as EmbodiedBench's subsets do.
"""

from __future__ import annotations

from .scene import (
    COUNTER_LEFT,
    COUNTER_RIGHT,
    SINK,
    SOFA,
    TABLE_1,
    TABLE_2,
    TV_STAND,
)

MOVE = (
    "Move {obj} from the {src} to the {dst}.",
    "Take {obj} from the {src} and put it on the {dst}.",
    "Bring {obj} over from the {src} to the {dst}.",
    "Could you carry {obj} from the {src} to the {dst}?",
    "Pick up {obj} at the {src} and set it down on the {dst}.",
)
MOVE_UNSOURCED = (
    "Put {obj} on the {dst}.",
    "I would like {obj} on the {dst}, please.",
    "Find {obj} and leave it on the {dst}.",
)
REMOVE = (
    "Clear the {obj} off the {src}.",
    "The {obj} should not stay on the {src}; move it somewhere else.",
    "Get the {obj} away from the {src}.",
)
TWO = (
    "Put {obj} and {obj2} on the {dst}.",
    "The {dst} needs {obj} and {obj2}.",
)
CLOSE_FRIDGE = ("The refrigerator was left open. Please shut it.", "Close the fridge door for me.")
OPEN_FRIDGE = ("Open the refrigerator, please.", "Leave the fridge door open.")
FROM_CONTAINER = (
    "Take the {obj} out of the {src} and put it on the {dst}.",
    "There is a {obj} inside the {src}; move it to the {dst}.",
)
WALK = ("Go to the {dst}.", "Walk over to the {dst}.")
CONDITIONAL = (
    "If the fridge is open, move {obj} to the {dst}; if it is closed, move {obj2} there instead.",
    "Depending on the refrigerator: open means {obj} goes to the {dst}, closed means {obj2} does.",
)
DISTRACTOR = (
    "There is {other} on the {other_at}, but what I need is {obj} on the {dst}.",
    "Never mind the {other} on the {other_at}; bring {obj} to the {dst}.",
)
MULTI = (
    "Move the {obj} to the {dst}, the {obj2} to the {dst2}, and the {obj3} to the {dst3}.",
    "Three errands: {obj} to the {dst}, {obj2} to the {dst2}, {obj3} to the {dst3}.",
)
MOVE_ALL = (
    "Move every {obj} from the {src} to the {dst}.",
    "All the {obj} items on the {src} belong on the {dst}.",
)


def a_noun(noun: str) -> str:
    """`apple` -> `an apple`; phrases that already start with an article or "something" pass through."""
    if noun.startswith(("a ", "an ", "something")):
        return noun
    return f"{'an' if noun[0] in 'aeiou' else 'a'} {noun}"


# common_sense: the object by what it is for or what it is like, never by its name.
CATEGORY_HINTS: dict[str, str] = {
    "ball": "something you can throw and catch",
    "clamp": "a tool that holds two pieces together while glue dries",
    "hammer": "a tool for driving nails",
    "screwdriver": "a tool for turning screws",
    "padlock": "something that locks a gate",
    "scissors": "something for cutting paper",
    "block": "a wooden toy piece for building towers",
    "drill": "a power tool that bores holes",
    "spatula": "a utensil for flipping pancakes",
    "knife": "a utensil for slicing bread",
    "spoon": "a utensil for eating soup",
    "plate": "something you serve dinner on",
    "sponge": "something for scrubbing dishes",
    "cleanser": "a bottle of cleaning liquid",
    "plum": "a small purple stone fruit",
    "pear": "a fruit shaped like a bell",
    "peach": "a fuzzy stone fruit",
    "apple": "a fruit that keeps the doctor away",
    "lemon": "a sour yellow citrus fruit",
    "can": "a tin of preserved food",
    "box": "a packaged food box",
    "banana": "a long fruit you peel",
    "strawberry": "a small red berry",
    "lego": "a plastic brick toy",
    "rubriks cube": "a twisting colour puzzle",
    "book": "something to read",
    "bowl": "something to eat cereal from",
    "cup": "something to drink from",
    "mug": "something for hot coffee",
    "orange": "a round citrus fruit you can juice",
    "lid": "something that covers a pan",
    "toy airplane": "a toy that looks like it could fly",
    "wrench": "a tool for tightening bolts",
}

# visual_appearance: the object by its looks.
CATEGORY_LOOKS: dict[str, str] = {
    "ball": "round sports item",
    "clamp": "metal gripping tool",
    "hammer": "tool with a heavy head",
    "screwdriver": "thin tool with a handle",
    "padlock": "small metal lock",
    "scissors": "pair of blades",
    "block": "wooden cube",
    "drill": "chunky power tool",
    "spatula": "flat kitchen utensil",
    "knife": "sharp silver utensil",
    "spoon": "small silver utensil",
    "plate": "flat round dish",
    "sponge": "soft rectangle",
    "cleanser": "plastic bottle",
    "plum": "dark purple fruit",
    "pear": "green bell-shaped fruit",
    "peach": "orange-pink fruit",
    "apple": "red fruit",
    "lemon": "yellow oval fruit",
    "can": "metal cylinder",
    "box": "cardboard package",
    "banana": "yellow curved fruit",
    "strawberry": "red berry",
    "lego": "colourful plastic brick",
    "rubriks cube": "cube with coloured squares",
    "book": "thing with pages",
    "bowl": "deep round dish",
    "cup": "small open container",
    "mug": "cup with a handle",
    "orange": "orange citrus fruit",
    "lid": "round cover with a knob",
    "toy airplane": "toy with wings",
    "wrench": "metal tool with an open jaw",
}

# visual_appearance: receptacles by their looks.
RECEPTACLE_APPEARANCE: dict[str, str] = {
    TABLE_1: "dark table",
    TABLE_2: "wooden brown table",
    TV_STAND: "low stand under the television",
    SINK: "washing basin",
    COUNTER_LEFT: "counter beside the refrigerator",
    COUNTER_RIGHT: "counter at the far end of the kitchen",
    SOFA: "big grey couch",
}

# spatial_relationship: kitchen receptacles by where they are relative to each other.
RECEPTACLE_SPATIAL: dict[str, str] = {
    SINK: "spot between the left and the right counters",
    COUNTER_LEFT: "counter to the left of the sink",
    COUNTER_RIGHT: "counter to the right of the sink",
}
