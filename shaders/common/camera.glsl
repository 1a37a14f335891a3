// camera.glsl — the ray through a pixel. Twin: Camera::ray (runtime/src/scene/camera.rs),
// with the camera's frame computed on the CPU (render_params.glsl).
#ifndef CAMERA_GLSL
#define CAMERA_GLSL

#include "common/render_params.glsl"

// The ray through continuous pixel (px, py) (centres at +0.5; y down): origin o, unit d.
void camera_ray(float px, float py, out vec3 o, out vec3 d) {
    GpuCamera c = params.camera;
    vec2 ndc = vec2(2.0 * px / float(c.size.x) - 1.0, 1.0 - 2.0 * py / float(c.size.y));
    vec2 s = ndc * c.half_extents;
    if (c.origin.w != 0.0) {
        vec3 v = c.forward.xyz + s.x * c.right.xyz + s.y * c.up.xyz;
        o = c.origin.xyz;
        d = v * (1.0 / length(v));
    } else {
        o = c.origin.xyz + s.x * c.right.xyz + s.y * c.up.xyz;
        d = c.forward.xyz;
    }
}

#endif // CAMERA_GLSL
