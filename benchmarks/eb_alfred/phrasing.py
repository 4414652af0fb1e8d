"""Instructions for generated EB-ALFRED tasks, in the five subset styles.

base: plain names ("Put a clean mug on the shelf."); common_sense: objects named by what they are
for; visual_appearance: by colour, shape or material; spatial: by where they are; and
complex_instruction: a base instruction wrapped in clauses that do not matter for the task. Every
phrase is written for this project; the choice among templates comes from the task's own RNG.
"""

from __future__ import annotations

import random
import re
from dataclasses import dataclass

__all__ = ["TaskWords", "instruction", "noun"]

# type: (what it is for, what it looks like)
_DESCRIBE: dict[str, tuple[str, str]] = {
    "Apple": ("a crisp fruit that keeps the doctor away", "the round red fruit"),
    "Bread": ("something you would make toast from", "the brown loaf"),
    "Lettuce": ("the leafy green that goes into salads", "the green leafy head"),
    "Potato": ("the starchy tuber that fries are made of", "the brown lumpy tuber"),
    "Tomato": ("the fruit ketchup is made from", "the small round red vegetable"),
    "Egg": ("what a hen lays", "the white oval shell"),
    "Knife": ("a sharp blade for cutting food", "the long steel blade"),
    "ButterKnife": ("a blunt knife for spreading", "the small silver blade"),
    "Fork": ("a pronged utensil for eating", "the silver pronged utensil"),
    "Spoon": ("the utensil for eating soup", "the small silver spoon"),
    "Spatula": ("a flat tool for flipping pancakes", "the flat black turner"),
    "Ladle": ("a deep spoon for serving soup", "the long-handled scoop"),
    "Mug": ("a handled cup for hot drinks", "the ceramic mug"),
    "Cup": ("a small container to drink from", "the clear glass"),
    "Bowl": ("a round dish for cereal", "the round bowl"),
    "Plate": ("a flat dish to eat from", "the round white plate"),
    "Pot": ("a deep vessel for boiling", "the deep metal pot"),
    "Pan": ("a shallow vessel for frying", "the black frying pan"),
    "Kettle": ("the thing you boil water in", "the metal kettle"),
    "DishSponge": ("what you scrub dishes with", "the yellow sponge"),
    "SaltShaker": ("the shaker for the salty seasoning", "the white shaker"),
    "PepperShaker": ("the shaker for the spicy black seasoning", "the dark shaker"),
    "SoapBottle": ("a bottle of liquid hand soap", "the pump bottle"),
    "WineBottle": ("a bottle that holds wine", "the dark green bottle"),
    "RemoteControl": ("the device for changing TV channels", "the black rectangular remote"),
    "KeyChain": ("the ring that keeps keys together", "the small metal key ring"),
    "CreditCard": ("a plastic card for paying", "the thin plastic card"),
    "Laptop": ("a portable computer", "the silver laptop"),
    "Pillow": ("a soft cushion for your head", "the soft square pillow"),
    "Newspaper": ("the printed daily news", "the folded grey paper"),
    "Statue": ("a small decorative sculpture", "the small stone figure"),
    "Vase": ("a container for showing off flowers", "the tall ceramic vase"),
    "Watch": ("something worn on the wrist to tell the time", "the wristwatch with a leather strap"),
    "Box": ("a cardboard container for storage", "the brown cardboard box"),
    "WateringCan": ("what you water the plants with", "the green can with a long spout"),
    "TissueBox": ("the box you pull tissues from", "the small patterned box"),
    "Book": ("something with pages to read", "the hardcover book"),
    "CellPhone": ("a handheld device for calls", "the black smartphone"),
    "AlarmClock": ("the clock that wakes you up", "the round clock with a bell"),
    "CD": ("a disc that stores music", "the shiny silver disc"),
    "Pen": ("a writing tool that uses ink", "the slim blue pen"),
    "Pencil": ("a writing tool made of graphite and wood", "the yellow pencil"),
    "BaseballBat": ("the club used to hit a baseball", "the wooden bat"),
    "TennisRacket": ("the strung racket for tennis", "the racket with a white frame"),
    "BasketBall": ("the ball you shoot through a hoop", "the orange ball"),
    "SoapBar": ("a solid bar for washing hands", "the white bar of soap"),
    "SprayBottle": ("a bottle with a trigger sprayer", "the blue spray bottle"),
    "Candle": ("a wax stick you light for a cosy glow", "the white wax candle"),
    "Cloth": ("a rag for wiping surfaces", "the folded rag"),
    "ToiletPaper": ("a roll of bathroom tissue", "the white paper roll"),
    "HandTowel": ("a small towel for drying hands", "the small white towel"),
    "Towel": ("a large towel for drying off after a shower", "the large folded towel"),
    "Plunger": ("the tool for unclogging a toilet", "the red rubber plunger"),
}
_PLACES: dict[str, str] = {
    "CounterTop": "counter", "SinkBasin": "sink", "GarbageCan": "trash can", "BathtubBasin": "bathtub",
    "TVStand": "TV stand", "ToiletPaperHanger": "toilet paper holder", "StoveBurner": "stove burner",
}
_PLACE_USES: dict[str, str] = {
    "CounterTop": "kitchen work surface", "DiningTable": "table where meals are eaten",
    "Fridge": "appliance that keeps food cold", "Microwave": "appliance that reheats food quickly",
    "SinkBasin": "basin under the tap", "GarbageCan": "bin for waste", "Shelf": "shelf", "Cabinet": "cupboard",
    "Drawer": "drawer", "Sofa": "couch", "ArmChair": "armchair", "CoffeeTable": "low table by the sofa",
    "SideTable": "small side table", "TVStand": "stand that holds the television", "Bed": "bed", "Desk": "desk",
    "Dresser": "chest of drawers", "Toilet": "toilet", "BathtubBasin": "tub", "StoveBurner": "stove burner",
    "CoffeeMachine": "coffee maker", "Toaster": "toaster", "LaundryHamper": "laundry basket",
    "TowelHolder": "towel rack", "HandTowelHolder": "hand towel ring", "ToiletPaperHanger": "toilet roll holder",
    "DeskLamp": "reading lamp", "FloorLamp": "tall standing lamp",
}
_OPENERS = (
    "Before the guests arrive, ", "Since the room is a bit messy, ", "While the radio is playing, ",
    "Even though the lights are dim, ", "After you glance out of the window, ", "Although a chair is in the way, ",
    "Without worrying about the dishes, ", "Now that the floor has been swept, ",
)
_CLOSERS = (
    "; leave everything else where it is.", ", and don't bother with the other things lying around.",
    "; the rest of the room can wait.", ", then take a short break.",
)


@dataclass(frozen=True)
class TaskWords:
    task_type: str
    obj: str
    sliced: bool
    parent: str = ""
    mrecep: str = ""
    lamp: str = ""
    source: str = ""
    neighbour: str = ""


def noun(type_name: str) -> str:
    """'ButterKnife' -> 'butter knife'; receptacles get their everyday names."""
    if type_name in _PLACES:
        return _PLACES[type_name]
    if type_name == "CD":
        return "CD"
    return re.sub(r"(?<=[a-z])(?=[A-Z])", " ", type_name).lower()


def _a(word: str) -> str:
    return ("an " if word[0].lower() in "aeiou" else "a ") + word


def _plural(word: str) -> str:
    if word.endswith("fe"):
        return word[:-2] + "ves"
    if word.endswith(("s", "x", "sh", "ch")):
        return word + "es"
    return word + "s"


def _object_phrase(w: TaskWords, style: str) -> str:
    base = noun(w.obj)
    if style == "common_sense" and w.obj in _DESCRIBE:
        core = _DESCRIBE[w.obj][0]
    elif style == "visual_appearance" and w.obj in _DESCRIBE:
        core = _DESCRIBE[w.obj][1]
    elif style == "spatial" and w.source:
        where = f"{_prep(w.source)} the {noun(w.source)}" + (f" next to the {noun(w.neighbour)}" if w.neighbour else "")
        core = f"the {base} {where}"
    else:
        core = _a(base)
    if w.sliced:
        return f"a slice of {core.removeprefix('a ').removeprefix('an ')}" if style == "base" else f"a slice from {core}"
    return core


_INSIDE = frozenset({
    "Fridge", "Cabinet", "Drawer", "GarbageCan", "SinkBasin", "BathtubBasin", "Microwave", "Safe", "LaundryHamper",
    "Box", "Bowl", "Cup", "Mug", "Pot", "Pan", "Toaster", "CoffeeMachine",
})


def _prep(type_name: str) -> str:
    return "in" if type_name in _INSIDE else "on"


def _place(type_name: str, style: str) -> str:
    if style == "common_sense" and type_name in _PLACE_USES:
        return "the " + _PLACE_USES[type_name]
    return "the " + noun(type_name)


def instruction(w: TaskWords, style: str, rng: random.Random) -> str:
    o, p = _object_phrase(w, style), _place(w.parent, style) if w.parent else ""
    on = _prep(w.parent)
    if w.task_type == "pick_two_obj_and_place":
        if w.sliced:
            two = f"two slices of {noun(w.obj)}" if style in ("base", "complex_instruction") else f"two slices like {o}"
        else:
            two = f"two {_plural(noun(w.obj))}" if style in ("base", "complex_instruction") else f"two items like {o}"
        text = rng.choice((f"Put {two} {on} {p}.", f"Place {two} {on} {p}.", f"Move {two} to {p}."))
    elif w.task_type == "look_at_obj_in_light":
        lamp = _place(w.lamp, style)
        text = rng.choice((f"Examine {o} under {lamp}.", f"Pick up {o} and turn on {lamp}.", f"Look at {o} by the light of {lamp}."))
    elif w.task_type == "pick_and_place_with_movable_recep":
        m = _object_phrase(TaskWords(w.task_type, w.mrecep, False, source=w.source), "base" if style == "spatial" else style)
        text = rng.choice((f"Put {o} in {m}, then move them to {p}.", f"Place {m} holding {o} {on} {p}."))
    else:
        verb = {"pick_clean_then_place_in_recep": ("Rinse", "Wash"), "pick_heat_then_place_in_recep": ("Heat", "Warm up"),
                "pick_cool_then_place_in_recep": ("Chill", "Cool")}.get(w.task_type)
        if verb:
            text = f"{rng.choice(verb)} {o} and put it {on} {p}."
        else:
            text = rng.choice((f"Put {o} {on} {p}.", f"Place {o} {on} {p}.", f"Move {o} to {p}."))
    if style == "complex_instruction":
        text = rng.choice(_OPENERS) + text[0].lower() + text[1:-1] + rng.choice(_CLOSERS)
    return text
