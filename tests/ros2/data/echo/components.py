"""The echo app of the ROS 2 tests: a level that rises, pushed back at every iteration."""

from rasm import Action, Anomaly, Plan


class EchoSimulator:
    def __init__(self, scenario=None, seed=0):
        self.level = 0.0

    def step(self, time, dt):
        self.level += dt
        return {"/level": {"data": self.level}}

    def apply(self, effector, message, time):
        self.level = message["data"]


class EchoMonitor:
    def monitor(self, ctx):
        return None


class EchoAnalyse:
    def analyse(self, ctx):
        level = ctx.knowledge.read_knowledge("level")
        return None if level is None else Anomaly(f"level {level:g}", {"level": level})


class EchoPlan:
    def plan(self, ctx):
        return Plan({"target": 0.0}, explanation="push the level back to zero")


class EchoExecute:
    def execute(self, ctx):
        return [Action("push", {"target": ctx.plan["target"]})]
