"""The ``rasm`` command line: ``main`` parses the arguments, calls the API and formats the result.

The screen of ``rasm run`` (a live view and the final summary, drawn with rich) lives here too,
in :mod:`rasm.cli.console`: the platform itself never draws.
"""

from rasm.cli.main import main

__all__ = ["main"]
