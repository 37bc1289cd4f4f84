// Pinhole rays through screen positions (renderers/projection.py camera_rays; u_tan = tan_half_fov):
// d = f + (2x/H - W/H) tan(fov/2) r + (1 - 2y/H) tan(fov/2) u, normalised -- in float64 with the CPU's order of
// operations, rounded to float32 once at the end (as the CPU's float64 rays are for Embree), so that both
// backends trace the same float32 rays.
uniform dvec3 u_cam_f;
uniform dvec3 u_cam_r;
uniform dvec3 u_cam_u;
uniform double u_tan;
uniform vec2 u_screen;   // W, H

vec3 camera_ray_d(dvec2 xy) {
    double W = double(u_screen.x), H = double(u_screen.y);
    precise double sx = (2.0LF * xy.x / H - W / H) * u_tan;
    precise double sy = (1.0LF - 2.0LF * xy.y / H) * u_tan;
    precise dvec3 d = u_cam_f + sx * u_cam_r;
    d = d + sy * u_cam_u;
    precise double n2 = d.x * d.x + d.y * d.y;
    n2 = n2 + d.z * d.z;
    return vec3(d / sqrt(n2));
}
vec3 camera_ray(vec2 xy) { return camera_ray_d(dvec2(xy)); }
