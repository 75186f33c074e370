// Job tables of the point drawer's compute passes (render/points/draw.py, render/points/follow.py): one uvec4
// per job whose last component is the exclusive prefix of the jobs' item counts, so a thread finds the job
// of its work item by binary search.
layout(std430, binding = 2) readonly buffer Jobs { uvec4 jobs[]; };
uniform uint u_njobs;

// the job holding work item g (largest j with jobs[j].w <= g)
uint find_job(uint g) {
    uint lo = 0u;
    uint hi = u_njobs - 1u;
    while (lo < hi) {
        uint mid = (lo + hi + 1u) >> 1;
        if (jobs[mid].w <= g) lo = mid; else hi = mid - 1u;
    }
    return lo;
}
