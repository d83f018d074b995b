"""rasm.verify: exhaustive verification of statecharts as they execute (``rasm verify``).

``verify_chart(path)`` explores every state a chart can reach under an environment, executed by
the interpreter ``rasm run`` uses, and judges past-time properties and the built-in problems
over all of them; ``verify_app(folder)`` does the same for the charts ``rasm run`` would run for
an app, bound as it binds them; see docs/verify.md.
"""

from rasm.verify.app import verify_app
from rasm.verify.chart import Counterexample, Finding, PropertyVerdict, Verification, verify_chart
from rasm.verify.environment import EnvEvent, Environment, load_environment

__all__ = [
    "Counterexample",
    "EnvEvent",
    "Environment",
    "Finding",
    "PropertyVerdict",
    "Verification",
    "load_environment",
    "verify_app",
    "verify_chart",
]
