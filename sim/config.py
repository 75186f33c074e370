"""Tunable constants of the simulation layer (upper-case, prefixed by module).

Tests import them; scene files set the per-effect parameters (``PARAMS``) instead.
"""
from __future__ import annotations

# --- sim.placement ------------------------------------------------------------
#: Span (seconds) of random initial animation times when the clip duration is
#: unknown: the animation system wraps modulo the duration, so phases are
#: uniform to within duration / span.
PLACEMENT_RANDOM_PHASE_SPAN = 3600.0
#: Dart-throwing tries per agent for ``random`` placement with min_distance.
PLACEMENT_RANDOM_TRIES = 30

# --- sim.instancing -----------------------------------------------------------
#: Largest instance count a hierarchy may flatten to.
INSTANCING_MAX_INSTANCES = 50_000_000

# --- sim.grid -----------------------------------------------------------------
#: A dense grid is used while (cells of the bounding box) <= GRID_DENSE_FACTOR * n;
#: beyond that, cell keys are hashed into 2^k >= 2 n buckets.
GRID_DENSE_FACTOR = 4
#: Cells per axis are capped at this (indices stay int32 for any spread of agents).
GRID_MAX_CELLS = 2 ** 30
#: Hash multipliers of cell coordinates (Teschner et al. 2003).
GRID_HASH_X = 73856093
GRID_HASH_Z = 19349663

# --- sim.boids ----------------------------------------------------------------
#: Speeds below this (m/s) count as standing still: heading is kept, the turn
#: limit does not apply, the forward direction falls back to the heading.
BOIDS_SPEED_EPS = 1e-6
#: Candidates examined per agent are capped at this multiple of max_neighbors
#: (bounds the cost of pathological crowds, e.g. 10,000 agents in one cell).
BOIDS_CANDIDATE_FACTOR = 8
#: Time constants (s) turning velocity differences and offsets into accelerations.
BOIDS_ALIGN_TAU = 1.0
BOIDS_COHESION_TAU = 2.0
BOIDS_CRUISE_TAU = 1.0
#: Golden-ratio constants for the deterministic push direction of coincident agents.
BOIDS_COINCIDENT_A = 0.6180339887498949
BOIDS_COINCIDENT_B = 0.7548776662466927

# --- sim.goals ----------------------------------------------------------------
#: Time constant (s) turning a velocity error into an acceleration.
GOALS_TAU = 0.5

# --- sim.obstacles ------------------------------------------------------------
#: Distances (m) below which a normal is taken from the edge instead of the offset.
OBSTACLES_EPS = 1e-9
#: Sphere tracing of a step's move stops at this gap (m) from an obstacle ...
OBSTACLES_CCD_EPS = 1e-6
#: ... or after this many iterations (a grazing move; the projection then applies).
OBSTACLES_CCD_ITERATIONS = 64
#: Agents within this gap (m) of an obstacle lose their velocity into it.
OBSTACLES_CONTACT = 1e-4

# --- sim.terrain --------------------------------------------------------------
#: Largest heightfield resolution (samples per side).
TERRAIN_MAX_RESOLUTION = 8192

# --- sim.avoidance ------------------------------------------------------------
#: Body radius (m) of an agent whose character index has no character (tests,
#: empty character lists); characters default to their footprint.
AVOIDANCE_DEFAULT_RADIUS = 0.25
#: Speeds (m/s) below this count as "no preferred motion" (heading and
#: animation rate are then left as the movers set them).
AVOIDANCE_SPEED_EPS = 1e-9
