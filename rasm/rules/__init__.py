"""rasm.rules: legitimacy rules, their z3 consistency proof and the run-time rule engine.

``load_rules`` reads and checks a rules file; ``verify`` proves what is wrong with it
(dead, unsatisfiable, conflicting, redundant rules); ``RuleSet`` is the Legitimate stage's
engine: rules compiled once, plans judged without z3, swaps refused unless consistent.
"""

from rasm.rules.engine import CompiledRules, Decision, RuleSet, SwapResult
from rasm.rules.loader import load_rules, parse_rules
from rasm.rules.model import Rule, Rules, Variable
from rasm.rules.report import Conflict, Report, Violation, format_json, format_text
from rasm.rules.verify import verify

__all__ = [
    "CompiledRules",
    "Conflict",
    "Decision",
    "Report",
    "Rule",
    "RuleSet",
    "Rules",
    "SwapResult",
    "Variable",
    "Violation",
    "format_json",
    "format_text",
    "load_rules",
    "parse_rules",
    "verify",
]
