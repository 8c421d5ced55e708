"""One-dimensional formation algorithms of Xu et al. (IET ITS 2021), pure numpy.

- :mod:`.targets`: interlaced / parallel target generation (Sec. 3.1-3.2,
  eq. (xy) corrected per docs/formation.md#target-equation).
- :mod:`.assignment`: minimum-cost vehicle-to-target assignment (Sec. 3.3).
- :mod:`.bezier`: cubic Bezier lane change and preview steering (Sec. 3.4).
- :mod:`.control`: longitudinal feedback law (Sec. 2.2, eq. (law)).
"""

from .assignment import (
    DEFAULT_W1,
    DEFAULT_W2,
    assign_targets,
    assignment_cost,
    total_cost,
)
from .bezier import (
    DEFAULT_MAX_STEER,
    DEFAULT_WHEELBASE,
    cubic_bezier,
    lane_change_control_points,
    lane_change_lateral,
    pure_pursuit_steering,
)
from .control import (
    DEFAULT_A_MAX,
    DEFAULT_A_MIN,
    DEFAULT_KP,
    DEFAULT_KV,
    longitudinal_feedback,
)
from .targets import (
    GEOMETRIES,
    formation_length,
    formation_targets,
    interlaced_targets,
    parallel_targets,
)

__all__ = [
    "DEFAULT_A_MAX",
    "DEFAULT_A_MIN",
    "DEFAULT_KP",
    "DEFAULT_KV",
    "DEFAULT_MAX_STEER",
    "DEFAULT_W1",
    "DEFAULT_W2",
    "DEFAULT_WHEELBASE",
    "GEOMETRIES",
    "assign_targets",
    "assignment_cost",
    "cubic_bezier",
    "formation_length",
    "formation_targets",
    "interlaced_targets",
    "lane_change_control_points",
    "lane_change_lateral",
    "longitudinal_feedback",
    "parallel_targets",
    "pure_pursuit_steering",
    "total_cost",
]
