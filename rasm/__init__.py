"""rasm: a statechart-first platform for trustworthy self-adaptive robots.

The RoboSAPIENS Adaptive Platform's MAPLE-K loop (Monitor, Analyse, Plan, Legitimate, Execute over
Knowledge), its building blocks driven by YAML statecharts executed with sismic, a temporal
property language checked online, and z3-checked legitimacy rules.
"""

__version__ = "0.1.0"
