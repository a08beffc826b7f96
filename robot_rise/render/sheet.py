"""The contact sheet: key frames tiled into one picture, a caption under each (Pillow)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from robot_rise.render.errors import RenderError
from robot_rise.render.labels import label_font

__all__ = ["contact_sheet"]


def contact_sheet(frames: Sequence[np.ndarray], labels: Sequence[str], *, columns: int = 4, title: str = "") -> np.ndarray:
    """Tile frames into one picture with a caption under each.

    Args:
        frames: RGB images of one size, shape (H, W, 3) each, uint8.
        labels: one caption per frame.
        columns: tiles per row (fewer if there are fewer frames).
        title: optional line above the tiles.

    Returns:
        RGB image, uint8, shape (rows * (H + caption) + title, columns * W + gaps, 3).
    """
    from PIL import Image, ImageDraw

    if not frames:
        raise RenderError("no frames for a contact sheet")
    h, w = frames[0].shape[:2]
    cols = max(1, min(columns, len(frames)))
    rows = math.ceil(len(frames) / cols)
    gap = 4
    font_px = max(10, h // 14)
    caption = font_px + 6
    top = caption + gap if title else 0
    sheet = Image.new("RGB", (cols * w + (cols + 1) * gap, top + rows * (h + caption + gap) + gap), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    font = label_font(font_px)
    if title:
        draw.text((gap, gap), title, fill=(0, 0, 0), font=font)
    for i, (img, text) in enumerate(zip(frames, labels)):
        r, c = divmod(i, cols)
        x = gap + c * (w + gap)
        y = top + gap + r * (h + caption + gap)
        sheet.paste(Image.fromarray(img), (x, y))
        draw.text((x + 2, y + h + 2), text, fill=(0, 0, 0), font=font)
    return np.asarray(sheet)
