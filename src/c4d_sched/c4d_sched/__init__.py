"""c4d_sched — offset (phase) assignment for non-preemptive cyclic executives and FIFO links.

ROS-free: GCD+ (thesis ch. 3) with its certificate and precedence variant, baselines, an exact
FIFO evaluator, a task-set generator, and the `c4d-sched` CLI. See docs/gcdplus.md.
"""

from .fifo import Evaluation, TaskMetrics, cycle_loads, evaluate, overlap
from .gcdplus import ORDER_VARIANTS, GcdPlusResult, Placement, gcd_plus, run_order
from .methods import METHODS, assign
from .model import Assignment, Chain, Task, TaskSet, TaskSetError

__all__ = [
    "METHODS", "ORDER_VARIANTS", "Assignment", "Chain", "Evaluation", "GcdPlusResult", "Placement",
    "Task", "TaskMetrics", "TaskSet", "TaskSetError", "assign", "cycle_loads", "evaluate", "gcd_plus",
    "overlap", "run_order",
]
