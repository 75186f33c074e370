"""VDR-AM cluster hierarchies for skinned characters (Claudio, Kim, Kim, Yoon), LOD mode ``"clusters"``.

Modules in data-flow order:

- ``lod.clusters.config``: the tunable constants, each naming its section.
- ``lod.clusters.poses``: pose-space reduction (MDS) and representative poses (§4, §4.1).
- ``lod.clusters.deformation``: per-vertex deformation levels (§4.2).
- ``lod.clusters.clustering``: error-aware leaf clustering and the octree baseline (§4.2, §6).
- ``lod.clusters.dag``: the cluster hierarchy in a flat layout, built bottom-up by multi-pose QEM with locked
  borders (§3.1, §4.3; ``lod.simplify``).
- ``lod.clusters.cut``: the per-instance cut by pixels of error (§5.1).
- ``lod.clusters.morph``: geomorphs between two cuts (Friedrich, Polthier & Schmies §3, applied to cuts).
- ``lod.clusters.mode``: ``ClustersRep``, the hierarchy cache, cluster frustum culling and the selector; the
  mode protocol.

Morph targets (glTF 2.0 §3.7.2.2) are ignored: hierarchies are built from and drawn as the skinned mesh at its
default morph weights (VDR-AM models skeletal motion only; see ``lod.clusters.mode``).
"""
