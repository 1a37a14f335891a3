#version 460
// hybrid_sky.frag — the environment behind the meshes (`fabric render --mesh`, `fabric
// view --envmap`): each pixel's camera ray read from the prefiltered map's sharpest
// level, as the tile pass shows a ray that misses the tile (common/trace.glsl); the
// plain background where the map is off or asked not to be seen (params.env_info.y).
#extension GL_GOOGLE_include_directive : require

#include "common/camera.glsl"
#include "common/env_lookup.glsl"

layout(location = 0) out vec4 out_color;

void main() {
    vec3 o;
    vec3 d;
    // gl_FragCoord is the pixel centre, y down: the continuous pixel camera_ray takes.
    camera_ray(gl_FragCoord.x, gl_FragCoord.y, o, d);
    vec3 c = params.background.rgb;
    if (HAS_ENV && params.env_info.y != 0u) {
        c = env_blurred(d, 0.0);
    }
    bool finite = !any(isnan(c)) && !any(isinf(c));
    out_color = vec4(finite ? c : vec3(0.0), 1.0);
}
