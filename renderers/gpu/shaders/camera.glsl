// Pinhole rays through screen positions: renderers/projection.py plane_offsets and ray_direction, generated
// (projection_gen.glsl), in float64 with the CPU's order of operations, rounded to float32 once at the end (as the
// CPU's float64 rays are for Embree), so that both backends trace the same float32 rays.
#include "projection_gen.glsl"
#include "camera_decl_gen.glsl"

vec3 camera_ray_d(dvec2 xy) {
    dvec2 s = proj_plane_offsets(xy.x, xy.y, double(u_screen.x), double(u_screen.y), u_tan);
    return vec3(proj_ray_direction(u_cam_f.x, u_cam_f.y, u_cam_f.z, u_cam_r.x, u_cam_r.y, u_cam_r.z, u_cam_u.x,
                                   u_cam_u.y, u_cam_u.z, s.x, s.y));
}
