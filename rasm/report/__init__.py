"""rasm.report: the transparency views (``rasm report``, ``rasm run --dashboard``).

``write_report(trace, output)`` writes one self-contained HTML page (plotly.js embedded): the
MAPLE-K stages as a Gantt over time, each stage's duration distribution, every property's verdict
timeline with its violations explained, the knowledge signals, and the adaptations table linked to
the timelines. ``rasm.report.dashboard.serve(platform, port)`` shows the same views live.
"""

from rasm.report.build import build_model, write_report
from rasm.report.model import TraceModel
from rasm.report.page import render_page

__all__ = ["TraceModel", "build_model", "render_page", "write_report"]
