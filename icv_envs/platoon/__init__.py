"""Improved virtual platoon at a multi-lane unsignalized intersection, pure numpy.

Paper Sec. 4-5 (Xu et al., IET ITS 2021), docs/intersection.md.  Simulator-independent
building blocks for the intersection environment:

- :mod:`.geometry`: legs, the 12 movements (id ``3 * leg + turn``), lane-use
  tables, approach / departure lanes and in-box lane paths.
- :mod:`.conflicts`: crossing / diverging / converging conflict model derived
  from the geometry and the lane-use table.
- :mod:`.tree`: tree-layers of the virtual platoon and reference positions.
- :mod:`.reservation`: first-come-first-served tile reservation (AIM), the
  paper's reference method.
"""

from .conflicts import (
    CONFLICT_KINDS,
    OPPOSING_LEFT_PAIRS,
    ConflictModel,
    conflict_model,
    conflicts_report,
    format_matrix,
    polyline_intersections,
    required_layer_gap,
)
from .geometry import (
    DEFAULT_BOX_HALF,
    DEFAULT_LANE_WIDTH,
    DEFAULT_N_POINTS,
    DEPARTURE_RULES,
    LANE_USE_PRESETS,
    LEGS,
    MOVEMENTS,
    N_LANES,
    TURNS,
    approach_centerline,
    approach_heading,
    departure_centerline,
    departure_lane,
    exit_heading,
    exit_leg,
    lane_path,
    lane_use_table,
    leg_index,
    movement_id,
    movement_name,
    path_headings,
    path_length,
    turn_index,
)
from .reservation import (
    DEFAULT_DT,
    DEFAULT_SPACE_BUFFER,
    DEFAULT_TILE,
    DEFAULT_TIME_BUFFER,
    DEFAULT_VEHICLE_LENGTH,
    DEFAULT_VEHICLE_WIDTH,
    ReservationTable,
    footprint_mask,
    footprint_tiles,
    simulate_path_occupancy,
    tile_grid,
    tile_of_point,
)
from .tree import (
    DEFAULT_D_T,
    follower_references,
    node_conflicts,
    reference_positions,
    tree_depths,
    tree_layers,
)

__all__ = [
    "CONFLICT_KINDS",
    "ConflictModel",
    "DEFAULT_BOX_HALF",
    "DEFAULT_DT",
    "DEFAULT_D_T",
    "DEFAULT_LANE_WIDTH",
    "DEFAULT_N_POINTS",
    "DEFAULT_SPACE_BUFFER",
    "DEFAULT_TILE",
    "DEFAULT_TIME_BUFFER",
    "DEFAULT_VEHICLE_LENGTH",
    "DEFAULT_VEHICLE_WIDTH",
    "DEPARTURE_RULES",
    "LANE_USE_PRESETS",
    "LEGS",
    "MOVEMENTS",
    "N_LANES",
    "OPPOSING_LEFT_PAIRS",
    "ReservationTable",
    "TURNS",
    "approach_centerline",
    "approach_heading",
    "conflict_model",
    "conflicts_report",
    "departure_centerline",
    "departure_lane",
    "exit_heading",
    "exit_leg",
    "follower_references",
    "footprint_mask",
    "footprint_tiles",
    "format_matrix",
    "lane_path",
    "lane_use_table",
    "leg_index",
    "movement_id",
    "movement_name",
    "node_conflicts",
    "path_headings",
    "path_length",
    "polyline_intersections",
    "reference_positions",
    "required_layer_gap",
    "simulate_path_occupancy",
    "tile_grid",
    "tile_of_point",
    "tree_depths",
    "tree_layers",
    "turn_index",
]
