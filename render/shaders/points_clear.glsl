#version 430
// Resets the per-pixel depth keys of the point splat to "empty".
layout(local_size_x = 256) in;
layout(std430, binding = 3) buffer Depth { uint depth[]; };
uniform uint u_pixels;

void main() {
    uint g = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 256u;
    if (g < u_pixels) depth[g] = 0xFFFFFFFFu;
}
