#version 330 core
// The ground plane: a quad centred under the camera reaching the far plane, in
// camera-relative coordinates (the camera at the origin), so it never loses
// float precision however far the camera is from the world origin.
in vec2 in_corner;  // (+-1, +-1)

uniform mat4 u_view_proj;
uniform float u_extent;      // half size of the quad, metres
uniform float u_plane_y;     // camera-relative height of the plane
uniform vec2 u_grid_phase;   // camera xz modulo 100 m (float64 on the CPU)

out vec3 v_world;
out vec2 v_grid;

void main() {
    v_world = vec3(in_corner.x * u_extent, u_plane_y, in_corner.y * u_extent);
    v_grid = v_world.xz + u_grid_phase;
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
