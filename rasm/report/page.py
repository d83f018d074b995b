"""Rendering the HTML page shared by ``rasm report`` and the live dashboard.

One template (``assets/report.html``), one style sheet and one script (``assets/report.js``)
draw the same model in both: the report embeds the model and plotly.js in the file, so it opens
without any network access; the dashboard's page loads plotly.js from the dashboard server and
follows the model over server-sent events.
"""

from __future__ import annotations

import html
import json
from functools import cache
from importlib import resources
from typing import Any

import rasm

__all__ = ["plotly_js", "render_page"]


def _asset(name: str) -> str:
    return resources.files("rasm.report").joinpath("assets", name).read_text(encoding="utf-8")


@cache
def plotly_js() -> str:
    """plotly.js, as shipped inside the plotly Python package (no network access)."""
    from plotly.offline import get_plotlyjs

    return get_plotlyjs()


def _inline_script(text: str) -> str:
    # a script element ends at the first "</script": keep the source from ending it early
    return text.replace("</script", "<\\/script")


def render_page(
    model: dict[str, Any] | None,
    *,
    title: str,
    events_url: str | None = None,
    plotly_url: str | None = None,
) -> str:
    """The page: ``model`` embedded (a report) or followed at ``events_url`` (a dashboard).

    plotly.js is embedded unless ``plotly_url`` says where the browser loads it from.
    """
    if plotly_url is None:
        plotly = f"<script>{_inline_script(plotly_js())}</script>"
    else:
        plotly = f'<script src="{html.escape(plotly_url)}"></script>'
    data = ""
    if model is not None:
        payload = json.dumps(model, allow_nan=False, separators=(",", ":"))
        payload = payload.replace("<", "\\u003c")  # no "</script>" inside the JSON
        data = f'<script type="application/json" id="rasm-data">{payload}</script>'
    attrs = f' data-events="{html.escape(events_url)}"' if events_url else ""
    parts = {
        "{{title}}": html.escape(title),
        "{{style}}": _asset("report.css"),
        "{{plotly}}": plotly,
        "{{body_attrs}}": attrs,
        "{{version}}": rasm.__version__,
        "{{data}}": data,
        "{{script}}": _inline_script(_asset("report.js")),
    }
    page = _asset("report.html")
    for key in ("{{title}}", "{{style}}", "{{body_attrs}}", "{{version}}", "{{data}}"):
        page = page.replace(key, parts[key])
    # the big parts last, so that nothing inside them is taken for a placeholder
    head, _, tail = page.partition("{{plotly}}")
    before, _, after = tail.partition("{{script}}")
    return head + plotly + before + parts["{{script}}"] + after
