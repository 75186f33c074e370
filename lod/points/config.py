"""Tunable constants of the point-sample hierarchy (Wand & Straßer 2002, §3).

Every ``lod/points_*`` module reads its defaults from here, so tests and
benchmarks can import and vary them. Names are upper case and prefixed
``POINTS_``; each says its unit, its accepted range and the paper's value.
"""
from __future__ import annotations

#: Maximum sample spacing r of a node as a fraction of the larger side of its
#: start and end bounding boxes (§3.3, §5.1: "1/8 - 1/16"). Accepted (0, 1].
POINTS_SPACING_FRACTION = 1.0 / 8.0

#: A triangle that receives more than this many kept (stratified) samples in a
#: node is stored there as a triangle and leaves the sampling below (§3.1:
#: "say 1-3"). Accepted >= 0.
POINTS_TRIANGLE_SAMPLES = 2

#: A node with at most this many triangles is a leaf and stores them without
#: sampling (§3.1: "e.g. at most 50 triangles"). Accepted >= 1.
POINTS_LEAF_TRIANGLES = 50

#: A triangle may exceed the child cube holding its centre by this fraction of
#: the child's side, else it stays at the inner node (§3.1: "say 10%").
POINTS_LOOSE_FRACTION = 0.10

#: Coupon-collector safety factor multiplying n ln n candidates (§3.4.1: "say 3
#: or 5"). Accepted > 0.
POINTS_SAFETY_FACTOR = 3.0

#: Number of time intervals per keyframe pair, each with its own stratified
#: point set (§3.4.2: "say 3 or 4"; §5.1: "between 3 and 5"). Their boundaries
#: follow the area change (``lod.points.stratify.choose_interval_times``; equal
#: for animated characters).
POINTS_TIME_INTERVALS = 3

#: Density of the filter set F relative to the number of bins n of the node
#: (§3.5 uses "ten times" the candidate density, i.e. 10 * safety * ln n bins;
#: we sample 10 n by default, about 25x the kept points, to keep the build
#: within budget; see ``lod.points.filter``).
POINTS_FILTER_FACTOR = 10.0

#: Standard deviation of the Gaussian attribute filter, as a fraction of the
#: node spacing r; the kernel is cut off at 2 sigma (= r/2 by default: the
#: splat radius). §3.5 only says the support is "relatively small".
POINTS_FILTER_SIGMA = 0.25

#: Hard cap on the candidates of one node (a guard against pathological
#: inputs such as thousands of coincident triangles); when hit, the node's
#: candidate count is clipped and coverage is no longer guaranteed there.
POINTS_MAX_CANDIDATES = 4_000_000

#: Depth limit of the octree; a node at this depth becomes a leaf whatever its
#: triangle count (coincident triangle centres cannot be separated).
POINTS_MAX_DEPTH = 24

#: Ratio of the voxel side h of the coupon-collector bins to the spacing r:
#: the paper sets r to two voxel diagonals (§3.4.1), h = r / (2 sqrt 3).
POINTS_BIN_RATIO = 1.0 / (2.0 * 3.0 ** 0.5)

#: Lengths and areas below this (relative to the root box) count as zero.
POINTS_EPS = 1e-12

#: Default bound on the pose error of the baked poses (lod.points.poses): the
#: largest vertex distance between the interpolated poses and the skinned
#: animation, as a fraction of the character's largest rest extent. 2 %
#: (3.7 cm on a 1.83 m humanoid) needs 14-15 poses for its 0.7-1.1 s walk and
#: run, where the earlier fixed 9 poses left 8-15 %.
POINTS_POSE_ERROR = 0.02

#: Cap on the poses baked per clip (each keyframe pair is one point hierarchy,
#: see POINTS_SEGMENT_BYTES_COEF: a 30 s varied clip of
#: a 3,000-triangle humanoid within 2 % needs ~450 poses, 0.8 GB; the memory
#: guard of crowd.memory refuses what does not fit, via memory_estimate).
POINTS_MAX_POSES = 1024

#: Bytes of point hierarchy per character triangle and keyframe segment with the
#: default parameters grow with the mesh (a finer mesh gets a deeper octree):
#: POINTS_SEGMENT_BYTES_COEF * triangles ** POINTS_SEGMENT_BYTES_EXP, fitted to
#: humanoids of 1,000 / 3,000 / 5,000 triangles (420 / 600 / 920 B measured).
POINTS_SEGMENT_BYTES_COEF = 13.3
POINTS_SEGMENT_BYTES_EXP = 0.487

#: Segments assumed per generated character before it is built (two clips of
#: about 15 poses each at the default pose_error)
GENERATOR_SEGMENTS = 30

#: The compute splat blends the points within this many splat footprints (in eye depth, at an anchor's
#: nearest point) behind an anchor's nearest (``[lod] splat_blend``; render/points/draw.py,
#: points_splat.glsl; 0 = the nearest point alone): one footprint spans ``s * w / f`` metres at eye depth w
#: (s the splat size, f the pixels per metre at depth 1). Measured (scripts/bench_splat_quality.md, frame 0
#: against the 4 x 4 reference): 0.5, 1, 2, 4 footprints gain +1.07, +1.43, +2.21, +2.72 dB over the nearest
#: point alone on the stadium, +0.58 .. +1.06 on the grid, +0.42 .. +0.88 on the exhibition, +0.95 .. +1.19
#: on the horses; 2 is within 0.5 dB of the best everywhere and blends across less than 4 does. Cost: the
#: colour pass loads every point within the tolerance (x1.1 .. x1.7 the splat's time, the most on the grid's
#: far view).
POINTS_SPLAT_BLEND = 2.0
