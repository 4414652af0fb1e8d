"""A top-down picture of what the twin's agent sees, for vision-language planners.

Drawn with PIL: the room (walls as a dark border), obstacles as grey boxes, the agent as a blue
triangle with its 100-degree view (light blue), and the objects in view as red dots, the nearest of
each type labelled with its type name.
Objects out of view are not drawn, so the picture says what the text says. World +x points right and
+z points up. Rendering takes 2-3 milliseconds, so the twin draws it only when somebody reads
`Observation.image` (or calls `env.render()`), never on the step hot path.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from benchmarks.eb_navigation.geometry import Scene
from benchmarks.eb_navigation.observe import FIELD_OF_VIEW, Pose, Sighting

if TYPE_CHECKING:
    from PIL import ImageDraw
    from PIL.Image import Image

__all__ = ["render_top_down", "IMAGE_SIZE"]

IMAGE_SIZE = 448  # a multiple of 28, which Qwen-VL image processors tile without padding
_PAD = 16
_BACKGROUND = (255, 255, 255)


def render_top_down(scene: Scene, pose: Pose, sightings: list[Sighting], size: int = IMAGE_SIZE) -> Image:
    """Draw the room, its obstacles, the agent's view and the objects in view (one label per type)."""
    from PIL import Image as PILImage
    from PIL import ImageDraw

    xmin, zmin, xmax, zmax = scene.room
    scale = (size - 2 * _PAD) / max(xmax - xmin, zmax - zmin)

    def px(x: float, z: float) -> tuple[float, float]:
        return _PAD + (x - xmin) * scale, size - _PAD - (z - zmin) * scale

    img = PILImage.new("RGB", (size, size), _BACKGROUND)
    draw = ImageDraw.Draw(img)
    left, top = px(xmin, zmax)
    right, bottom = px(xmax, zmin)
    draw.rectangle([left, top, right, bottom], fill=(238, 238, 232))
    _draw_view(draw, pose, px(pose.x, pose.z), 2 * size)
    for o in scene.objects:
        if o.half is not None:
            hx, hz = o.half
            draw.rectangle([px(o.x - hx, o.z + hz), px(o.x + hx, o.z - hz)], fill=(170, 170, 170))
    for box in ([0, 0, size, top], [0, bottom, size, size], [0, 0, left, size], [right, 0, size, size]):
        draw.rectangle(box, fill=_BACKGROUND)  # clip the view and obstacles to the room
    draw.rectangle([left, top, right, bottom], outline=(40, 40, 40), width=4)
    _draw_agent(draw, pose, px(pose.x, pose.z), max(6.0, 0.2 * scale))
    labelled: set[str] = set()
    for s in sightings:  # nearest first: the label goes on the nearest of each type, as in the text
        cx, cy = px(s.x, s.z)
        draw.ellipse([cx - 4, cy - 4, cx + 4, cy + 4], fill=(210, 30, 30))
        if s.type not in labelled:
            labelled.add(s.type)
            draw.text((cx + 6, cy - 6), s.type, fill=(120, 0, 0))
    return img


def _heading_angle(rotation: float) -> float:
    """PIL's angle (degrees, clockwise from image +x) of the direction the agent faces."""
    theta = math.radians(rotation)
    return math.degrees(math.atan2(-math.cos(theta), math.sin(theta)))


def _draw_view(draw: ImageDraw.ImageDraw, pose: Pose, centre: tuple[float, float], radius: float) -> None:
    cx, cy = centre
    angle = _heading_angle(pose.rotation)
    half = FIELD_OF_VIEW / 2
    draw.pieslice(
        [cx - radius, cy - radius, cx + radius, cy + radius], angle - half, angle + half, fill=(205, 222, 255)
    )


def _draw_agent(draw: ImageDraw.ImageDraw, pose: Pose, centre: tuple[float, float], r: float) -> None:
    cx, cy = centre
    theta = math.radians(pose.rotation)
    points = [
        (cx + r * math.sin(theta + offset), cy - r * math.cos(theta + offset)) for offset in (0.0, 2.5, -2.5)
    ]
    draw.polygon(points, fill=(30, 60, 200))
