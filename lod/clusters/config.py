"""Tunable constants of the VDR-AM cluster hierarchy (Claudio, Kim, Kim, Yoon).

Upper-case ``CLUSTERS_`` names so tests and benchmarks can import them; every
constant names the module and the paper section it feeds.
"""

# ---------------------------------------------------------------- §4 / §4.1 poses (lod/clusters/poses.py)
CLUSTERS_MDS_DIMS = 9
"""Dimensions of the reduced pose space (§4, after Assa et al.)."""

CLUSTERS_POSE_D_FRACTION = 0.2
"""Pose-clustering distance d as a fraction of the rest-pose box diagonal
(§6 recommends 10 %..30 %). d is measured in the MDS space of joint-position
vectors, metres (see :func:`lod.clusters.poses.pose_features`)."""

CLUSTERS_POSE_SPLIT_FACTOR = 1.5
"""§4.1 partitioning: split a pose group whose box diagonal exceeds this times d."""

CLUSTERS_POSE_SAMPLES = 35
"""Poses sampled uniformly over each clip's duration (the paper's walk has 35)."""

# ---------------------------------------------------------------- §4.2 clustering (lod/clusters/clustering.py)
CLUSTERS_DEFORM_TOLERANCE = 0.10
"""§4.2: deformation levels of one cluster lie within this fraction of the
model's largest deformation level."""

CLUSTERS_LEAF_TRIANGLES = 100
"""§4.2 s: a leaf cluster holds at most this many triangles."""

CLUSTERS_WEIGHT_EPS = 1e-4
"""Skin weights at or below this do not count as an influencing bone (§4.2 LCA)."""

# ---------------------------------------------------------------- §4.3 hierarchy (lod/clusters/dag.py, lod/simplify/collapse.py)
CLUSTERS_SIMPLIFY_RATIO = 0.5
"""§4.3: each parent cluster keeps this fraction of its children's triangles."""


CLUSTERS_SPHERE_PAD = 0.5
"""Bounding spheres grow by this times the largest displacement of a cluster
vertex between two consecutive sampled poses, so poses between samples stay inside."""

CLUSTERS_PROGRESS_SECONDS = 1.0
"""Builds expected to take longer than this show a tqdm progress bar."""

# ---------------------------------------------------------------- §5.1 cut (lod/clusters/cut.py)
CLUSTERS_DEFAULT_POE = 0.5
"""Pixels of error used by the paper at 1280x720 (§6)."""
