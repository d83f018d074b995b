"""rasm.scale: many recordings, and large ones, checked in parallel — in local processes or on
a Dask distributed cluster (``rasm check PROPS RECORDING... --jobs N | --cluster ADDRESS``)."""

from rasm.scale.engines import ClusterError, DaskCluster, Engine, InProcess, Processes, WorkerLost
from rasm.scale.many import MIN_PART, Outcome, check_many, plan_parts
from rasm.scale.recordings import Checked, Job, RecordingError, check_recording, is_trace

__all__ = [
    "MIN_PART", "Checked", "ClusterError", "DaskCluster", "Engine", "InProcess", "Job",
    "Outcome", "Processes", "RecordingError", "WorkerLost", "check_many", "check_recording",
    "is_trace", "plan_parts",
]
