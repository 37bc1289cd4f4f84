// Pinhole rays through screen positions (renderers/tracer.py camera_rays):
// d = f + (2x/H - W/H) tan(fov/2) r + (1 - 2y/H) tan(fov/2) u, normalised.
uniform vec3 u_cam_f;
uniform vec3 u_cam_r;
uniform vec3 u_cam_u;
uniform float u_tan;
uniform vec2 u_screen;   // W, H

vec3 camera_ray(vec2 xy) {
    float sx = (2.0 * xy.x / u_screen.y - u_screen.x / u_screen.y) * u_tan;
    float sy = (1.0 - 2.0 * xy.y / u_screen.y) * u_tan;
    return normalize(u_cam_f + sx * u_cam_r + sy * u_cam_u);
}
