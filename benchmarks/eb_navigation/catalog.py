"""What generated rooms are made of, and how generated instructions name objects.

Room kinds and target types follow EB-Navigation's own episodes (kitchens, living rooms, bedrooms;
targets such as Pot, Toaster, GarbageCan, Laptop, AlarmClock). Furniture sizes are rough iTHOR sizes.
Every description below is written for this project (not EmbodiedBench's text).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Furniture", "ROOMS", "FLOOR_OBJECTS", "DESCRIPTIONS", "AMBIENT", "REQUESTS"]


@dataclass(frozen=True, slots=True)
class Furniture:
    """A piece of furniture: type, footprint (along the wall, depth), surface height, where it goes,
    and which small objects may sit on it."""

    type: str
    size: tuple[float, float]
    height: float
    place: str  # "wall" (back against a wall) or "center"
    holds: tuple[str, ...] = ()


ROOMS: dict[str, tuple[Furniture, ...]] = {
    "kitchen": (
        Furniture("CounterTop", (2.2, 0.65), 0.9, "wall",
                  ("Bread", "Toaster", "CoffeeMachine", "Kettle", "Pot", "Cup", "Tomato", "Lettuce", "StoveBurner")),
        Furniture("CounterTop", (1.6, 0.65), 0.9, "wall", ("Mug", "Apple", "Bowl", "Pan", "Kettle", "Toaster")),
        Furniture("Fridge", (0.8, 0.75), 0.9, "wall"),
        Furniture("DiningTable", (1.2, 0.8), 0.75, "center", ("Cup", "Bowl", "Apple", "Plate", "Bread", "Tomato")),
    ),
    "living_room": (
        Furniture("Sofa", (2.0, 0.9), 0.45, "wall", ("Pillow",)),
        Furniture("TVStand", (1.5, 0.5), 0.5, "wall", ("Box", "Vase", "Statue")),
        Furniture("CoffeeTable", (1.1, 0.6), 0.45, "center", ("TissueBox", "Box", "Laptop", "Vase", "Plate")),
        Furniture("SideTable", (0.5, 0.5), 0.6, "wall", ("DeskLamp", "Statue", "TissueBox")),
        Furniture("ArmChair", (0.9, 0.9), 0.45, "wall", ("Pillow",)),
    ),
    "bedroom": (
        Furniture("Bed", (1.6, 2.0), 0.5, "wall", ("Pillow", "Laptop", "Book", "CellPhone")),
        Furniture("Desk", (1.3, 0.65), 0.75, "wall", ("Laptop", "DeskLamp", "Book", "AlarmClock", "Mug")),
        Furniture("Dresser", (1.2, 0.5), 0.8, "wall", ("AlarmClock", "Box", "Bowl", "Vase")),
        Furniture("SideTable", (0.5, 0.5), 0.6, "wall", ("DeskLamp", "AlarmClock", "CellPhone", "Book")),
    ),
}  # fmt: skip

# Objects that stand on the floor against a wall, per room kind: (type, footprint side).
FLOOR_OBJECTS: dict[str, tuple[tuple[str, float], ...]] = {
    "kitchen": (("GarbageCan", 0.35),),
    "living_room": (("GarbageCan", 0.35), ("FloorLamp", 0.4)),
    "bedroom": (("GarbageCan", 0.35), ("LaundryHamper", 0.5), ("Safe", 0.5)),
}

# type -> (spoken name, what it is for, what it looks like)
DESCRIPTIONS: dict[str, tuple[str, str, str]] = {
    "Bread": ("bread", "something baked that I can slice for toast", "oblong golden-brown item with a soft crust"),
    "Toaster": ("toaster", "the appliance that browns slices of bread", "boxy metal appliance with two slots on top"),
    "CoffeeMachine": ("coffee machine", "the machine that brews my morning drink", "tall dark appliance with a spout and a drip tray"),
    "Kettle": ("kettle", "something to boil water for tea", "rounded metal vessel with a handle and a spout"),
    "Pot": ("pot", "a deep vessel for cooking soup on the stove", "deep round dark container with two handles"),
    "Pan": ("pan", "a flat vessel for frying eggs", "wide shallow black item with a long handle"),
    "Cup": ("cup", "something I can pour water into and drink from", "small plain cylindrical container"),
    "Mug": ("mug", "a drinking vessel for hot coffee", "chunky cylindrical vessel with a loop handle"),
    "Tomato": ("tomato", "a juicy vegetable for a salad", "small round shiny red item"),
    "Lettuce": ("lettuce", "leafy greens for a salad", "round bundle of crinkly green leaves"),
    "Apple": ("apple", "a crunchy fruit for a snack", "small round fruit with a glossy skin and a short stem"),
    "Bowl": ("bowl", "something to serve cereal in", "round open dish with curved sides"),
    "Plate": ("plate", "something flat to serve a meal on", "flat round white dish"),
    "StoveBurner": ("stove burner", "the place where a pan gets heated", "dark circular grate on the cooktop"),
    "GarbageCan": ("garbage can", "somewhere to throw away rubbish", "upright open-topped bin standing on the floor"),
    "Pillow": ("pillow", "something soft to rest my head on", "soft square cushion with a plain cover"),
    "Box": ("box", "something to store small things in", "plain cardboard cube with folded flaps"),
    "Vase": ("vase", "a container to hold cut flowers", "slender glazed vessel with a narrow neck"),
    "Statue": ("statue", "a decorative sculpture", "small carved figure standing on a base"),
    "TissueBox": ("tissue box", "something that gives me a tissue to blow my nose", "small rectangular box with a slit on top"),
    "Laptop": ("laptop", "a portable computer for my work", "thin folding device with a screen and a keyboard"),
    "DeskLamp": ("desk lamp", "a small light for reading at a table", "short lamp with a bent neck and a round shade"),
    "FloorLamp": ("floor lamp", "a tall light that brightens a corner", "tall thin pole with a shade at the top"),
    "Book": ("book", "something to read before bed", "rectangular bound object with a printed cover"),
    "CellPhone": ("cell phone", "the device I use to call a friend", "small flat black rectangle with a glass face"),
    "AlarmClock": ("alarm clock", "the thing that wakes me up in the morning", "small round-faced device with two bells"),
    "LaundryHamper": ("laundry hamper", "somewhere to put my dirty clothes", "woven basket with a lid standing on the floor"),
    "Safe": ("safe", "a locked place for my valuables", "heavy metal cube with a dial on its door"),
}  # fmt: skip

AMBIENT: tuple[str, ...] = (
    "The afternoon light makes long stripes across the floor.",
    "Somewhere outside a dog keeps barking at the mail carrier.",
    "A faint smell of fresh paint still hangs in the air.",
    "The radio in the next room is playing an old jazz record.",
    "Rain has been drumming on the roof since the morning.",
    "A stack of unopened letters waits by the door.",
    "The heater ticks quietly as it warms up.",
    "Someone left a half-finished crossword on a chair.",
    "The curtains move a little in the draft from the window.",
    "It has been a long and busy week around here.",
)

REQUESTS: tuple[str, ...] = (
    "Could you go over to the {name} and stay right next to it?",
    "Please head to the {name} and get as close to it as you can.",
    "Would you walk up to the {name} and remain beside it?",
    "Please make your way to the {name} and stop close to it.",
)
