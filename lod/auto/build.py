"""Mode "auto" as ``lod.modes`` names it (the registry's module of the mode): its ``[lod]`` keys
(:data:`lod.auto.params.PARAMS`), its build (the candidates' representations and an
:class:`lod.auto.mode.AutoSelector`) and its memory estimate. The selector's module does not import this one."""
from __future__ import annotations

from lod.auto import candidates as ac
from lod.auto.mode import AutoSelector
from lod.auto.params import PARAMS, parse_candidates
from lod.chains import mode as tm
from lod.far.build import build_far_split


def build(characters, names, fps, params, static_reps=(), progress=None, cache: bool = True, model=None,
          points_params=None, instancing=None, clips=None, variation=None):
    """Mode "auto" for ``lod.modes``: the "triangles" mode's reps (full-detail
    reps for non-skinned characters), the cluster hierarchies and point
    hierarchies of the characters when those candidates are asked for, and
    an :class:`AutoSelector`.

    Parameters
    ----------
    characters, names, fps, params, static_reps, progress : see ``lod.modes``
    cache : use the on-disk chain and cluster caches (default); point
        hierarchies always use theirs (``lod.points.rep.HierarchyCache``)
    model : a :class:`lod.auto.cost_model.CostModel` (default: stored calibration or defaults)
    points_params : further ``[lod]`` keys of mode "points" for the point
        candidate's hierarchies (e.g. ``{"intervals": 1}``)
    instancing : the simulation's ``sim.instancing.Instancing`` (or None):
        the point candidate draws far nodes of its groups from
        super-hierarchies (Wand & Straßer §3.6), as mode "points" does
    clips : the clips the scene can play per character (see
        ``lod.points.mode.build``): point hierarchies only for those
    variation : the agents' colour-variation words (``lod.variation``) or None: the
        super-hierarchies carry them (see ``lod.points.mode.build_instancing``)

    Returns
    -------
    reps : every representation to upload (triangle reps first, aligned with
        the characters; then the clusters and points reps)
    selector : AutoSelector
    """
    params = dict(params or {})
    poe = float(params.get("poe", PARAMS["poe"].default))
    budget = float(params.get("budget_ms", PARAMS["budget_ms"].default))
    names_c = parse_candidates(params.get("candidates", PARAMS["candidates"].default))
    tri_params = {k: params[k] for k in ("levels", "ratio") if k in params}
    tri_params["poe"] = poe
    reps, tsel = tm.build(characters, names, fps, tri_params, static_reps=static_reps, progress=progress, cache=cache)
    delegates = {"triangles": tsel}
    extra = []
    if "clusters" in names_c and any(getattr(c, "kind", "") == "skinned" for c in characters):
        from lod.clusters import mode as clusters_mode

        cp = {"leaf_triangles": int(params.get("leaf_triangles", PARAMS["leaf_triangles"].default))}
        creps, delegates["clusters"] = clusters_mode.build(characters, names, fps, cp, static_reps=static_reps, progress=progress,
                                       cache=cache)
        extra.append(ac.ClustersCandidate(creps, error_scale=float(params.get(
            "cluster_error_scale", PARAMS["cluster_error_scale"].default))))
    if "points" in names_c and characters:
        from lod.points import mode as points_mode

        pp = {**dict(points_params or {}),
              **{k: params.get(k, PARAMS[k].default) for k in ("keyframes", "pose_error", "max_keyframes")}}
        preps, psel = points_mode.build(characters, names, fps, pp, static_reps=static_reps, progress=progress,
                                        instancing=instancing, clips=clips, variation=variation)
        strict = str(params.get("points_error", PARAMS["points_error"].default)) == "splat+keyframes"
        # the pose error of the poses the hierarchies were built over (lod.points.poses; loop jumps excluded)
        dev = [max((cp.error for cp in r.poses.values()), default=0.0) if strict else 0.0
               for r in preps[:len(characters)]]
        extra.append(ac.PointsCandidate(preps, [r.kind for r in reps],
                                        max_splat=int(params.get("max_splat", PARAMS["max_splat"].default)),
                                        deviation=dev, spheres=[getattr(r, "clip_sphere", None) for r in reps],
                                        instancing=psel.instancing))
    if "points" in names_c and characters:
        delegates["points"] = psel
    far = None  # the far tier (lod.far) before the choice; not beside instancing groups (their super nodes)
    if not getattr(instancing, "groups", None):
        far = build_far_split(characters, names, fps, clips,
                              float(params.get("far_pixels", PARAMS["far_pixels"].default)))
    sel = AutoSelector(reps, static_reps=static_reps, poe=poe, budget_ms=budget, model=model, candidates=extra,
                       delegates=delegates, far=far,
                       adapt=bool(params.get("adapt", PARAMS["adapt"].default)),
                       explore=bool(params.get("explore", PARAMS["explore"].default)),
                       switch_frames=int(params.get("switch_frames", PARAMS["switch_frames"].default)))
    return sel.candidate_reps + (far.uploads if far is not None else []), sel


def memory_estimate(characters, params: dict) -> int:
    """Bytes of the candidates' hierarchies (``crowd.memory``'s hook): the point candidate's as mode points
    estimates them (:func:`lod.points.mode.memory_estimate` with this mode's pose keys), the cluster
    candidate's at 80 bytes per triangle."""
    from lod.points import mode as points_mode

    names = parse_candidates(params.get("candidates", PARAMS["candidates"].default))
    total = 0
    if "points" in names:
        total += points_mode.memory_estimate(characters, {k: params[k] for k in ("keyframes", "pose_error",
                                                                               "max_keyframes") if k in params})
    if "clusters" in names:
        for ch in characters:
            mesh = getattr(ch, "mesh", None)
            tris = (mesh.n_triangles if mesh is not None
                    else int(getattr(ch, "triangles", 0) or 0))
            total += 80 * tris
    return int(total)


__all__ = ["PARAMS", "build", "memory_estimate"]
