"""The wide app of the ROS 2 tests: every other plan's speed does not fit a float32."""

from rasm import Action, Anomaly, Plan


class Robot:
    def __init__(self, scenario=None, seed=0):
        self.speeds = []

    def step(self, time, dt):
        return {"/level": {"data": float(len(self.speeds))}}

    def apply(self, effector, message, time):
        self.speeds.append(message["data"])


class Quiet:
    def monitor(self, ctx):
        return None


class Always:
    def analyse(self, ctx):
        return Anomaly("act")


class Alternate:
    def __init__(self):
        self.n = 0

    def plan(self, ctx):
        self.n += 1
        return Plan({"speed": 1e39 if self.n % 2 else 0.5})


class Drive:
    def execute(self, ctx):
        return [Action("drive", {"speed": ctx.plan["speed"]})]
