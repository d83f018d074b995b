"""The guard app of the ROS 2 tests: slow down when something is close ahead."""

from rasm import Action, Anomaly, Plan


class GuardMonitor:
    def monitor(self, ctx):
        return None


class GuardAnalyse:
    def analyse(self, ctx):
        k = ctx.knowledge
        speed, ahead = k.read_knowledge("speed"), k.read_knowledge("ahead")
        if speed is None or ahead is None:
            return None
        if ahead < 0.5 and speed > 0.3:
            return Anomaly(f"{speed:g} m/s with an obstacle {ahead:g} m ahead", {"ahead": ahead})
        return None


class GuardPlan:
    def plan(self, ctx):
        return Plan({"speed": 0.1, "turn": 0.5}, explanation="slow down and turn away")


class GuardExecute:
    def execute(self, ctx):
        return [
            Action("drive", {"speed": ctx.plan["speed"], "turn": ctx.plan["turn"]}),
            Action("state", {"level": 2, "reason": "obstacle ahead"}),
        ]
