"""Text drawn onto pictures (Pillow): the font, and a caption in a frame's top left corner."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["label_font", "draw_label"]


def label_font(size_px: int) -> Any:
    """Pillow's default font at ``size_px`` (its one fixed size on Pillow < 10.1)."""
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size_px)
    except TypeError:  # Pillow < 10.1 has one fixed-size default font
        return ImageFont.load_default()


def draw_label(img: np.ndarray, text: str) -> np.ndarray:
    """``img`` with ``text`` in its top left corner, dark on a light outline (any background)."""
    from PIL import Image, ImageDraw

    pil = Image.fromarray(img)
    size = max(10, img.shape[0] // 20)
    ImageDraw.Draw(pil).text(
        (size // 2, size // 2), text, fill=(20, 20, 20), font=label_font(size), stroke_width=max(1, size // 8), stroke_fill=(255, 255, 255)
    )
    return np.asarray(pil).copy()
