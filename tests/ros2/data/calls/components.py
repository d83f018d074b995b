"""The calls app of the ROS 2 tests: once the robot's heartbeat is in, one action doubles a
number through a service and one pursues a Fibonacci goal (test_msgs' interfaces)."""

from rasm import Action, Anomaly, Plan


class CallsMonitor:
    def monitor(self, ctx):
        return None


class CallsAnalyse:
    def __init__(self):
        self.asked = False

    def analyse(self, ctx):
        if self.asked or ctx.knowledge.read_knowledge("beat") is None:
            return None
        self.asked = True
        return Anomaly("the robot is up: ask it", {})


class CallsPlan:
    def plan(self, ctx):
        return Plan({"order": 6, "value": 21}, explanation="double 21, six Fibonacci numbers")


class CallsExecute:
    def execute(self, ctx):
        return [Action("double", {"value": ctx.plan["value"]}),
                Action("fibonacci", {"order": ctx.plan["order"]})]
