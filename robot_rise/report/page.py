"""The HTML of the report: its CSS, ``data:`` URIs, JSON values as tables, the verdict banner and the whole page.

Everything is inline (no script, no link outside the page), so the page can be mailed or archived
as one file.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence
from typing import Any

__all__ = ["PAGE_CSS", "data_uri", "img_html", "value_html", "verdict_html", "page_html"]

PAGE_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; padding: 0 1em; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; } h2 { font-size: 1.15em; margin-top: 1.8em; border-bottom: 1px solid #ccc; }
.verdict { padding: 0.8em 1em; border-radius: 6px; font-size: 1.1em; }
.ok { background: #e3f4e1; border: 1px solid #7bbf73; } .bad { background: #fbe4e1; border: 1px solid #d98277; }
img, video { max-width: 100%; height: auto; display: block; margin: 0.5em 0; }
table { border-collapse: collapse; font-size: 0.9em; margin: 0.4em 0; }
td, th { border: 1px solid #ddd; padding: 2px 8px; text-align: left; vertical-align: top; }
th { background: #f4f4f4; font-weight: 600; } td.num { font-family: ui-monospace, monospace; }
.note { color: #666; font-size: 0.85em; }
"""


def data_uri(mime: str, payload: bytes) -> str:
    """``payload`` as a base64 ``data:`` URI of type ``mime``."""
    return f"data:{mime};base64,{base64.b64encode(payload).decode('ascii')}"


def img_html(payload: bytes, alt: str, mime: str = "image/png") -> str:
    """An ``<img>`` embedding ``payload`` (an image of type ``mime``)."""
    return f'<img src="{data_uri(mime, payload)}" alt="{html.escape(alt)}">'


def _fmt(value: Any) -> str:
    if isinstance(value, bool) or value is None:
        return html.escape(str(value).lower() if isinstance(value, bool) else "null")
    if isinstance(value, float):
        return html.escape(f"{value:.6g}")
    return html.escape(str(value))


def value_html(value: Any) -> str:
    """Any JSON value as HTML: objects as tables, lists of scalars inline, the rest recursively."""
    if isinstance(value, dict):
        if not value:
            return "<i>empty</i>"
        rows = "".join(f"<tr><th>{html.escape(str(k))}</th>{_cell(v)}</tr>" for k, v in value.items())
        return f"<table>{rows}</table>"
    if isinstance(value, (list, tuple)):
        if all(not isinstance(v, (dict, list, tuple)) for v in value):
            return ", ".join(_fmt(v) for v in value) if value else "<i>none</i>"
        return "<ol start=0>" + "".join(f"<li>{value_html(v)}</li>" for v in value) + "</ol>"
    return _fmt(value)


def _cell(value: Any) -> str:
    numeric = isinstance(value, (int, float)) and not isinstance(value, bool)
    return f'<td class="num">{value_html(value)}</td>' if numeric else f"<td>{value_html(value)}</td>"


def verdict_html(proven: bool, scene: str, summary: str, problems: Sequence[str]) -> str:
    """The banner at the top: PROVEN or NOT PROVEN in ``scene``, the judge's ``summary``, the problems listed."""
    items = "".join(f"<li>{html.escape(p)}</li>" for p in problems)
    return (
        f'<div class="verdict {"ok" if proven else "bad"}"><b>{"PROVEN" if proven else "NOT PROVEN"}</b> in scene '
        f"{html.escape(scene)} — {html.escape(summary)}" + (f"<ul>{items}</ul>" if items else "") + "</div>"
    )


def page_html(title: str, sections: Sequence[tuple[str, str]], head: str) -> str:
    """The whole page: ``title``, then ``head`` (HTML), then each (heading, HTML content) section."""
    body = "".join(f"<h2>{html.escape(name)}</h2>\n{content}\n" for name, content in sections)
    return (
        "<!DOCTYPE html>\n<html lang=en>\n<head>\n<meta charset=utf-8>\n"
        f"<title>{html.escape(title)}</title>\n<style>{PAGE_CSS}</style>\n</head>\n<body>\n"
        f"<h1>{html.escape(title)}</h1>\n{head}\n{body}</body>\n</html>\n"
    )
