// lights.glsl — incident light at a point, directional or point.
//
// Rust twin: runtime/src/scene/light.rs (`Light::sample`). Conventions
// (DESIGN.md §8): a directional light's vector points *toward* the light and its power
// is irradiance perpendicular to the beam; a point light's power is intensity per
// steradian with 1/d² falloff.
#ifndef LIGHTS_GLSL
#define LIGHTS_GLSL

// light_vec.w = 0: directional, xyz = unit vector toward the light.
// light_vec.w = 1: point light at xyz.
// Returns the irradiance perpendicular to `wi` (the unit direction toward the light).
vec3 light_incident(vec4 light_vec, vec3 light_power, vec3 p, out vec3 wi, out float dist) {
    if (light_vec.w == 0.0) {
        wi = light_vec.xyz;
        dist = 1.0 / 0.0; // +inf
        return light_power;
    }
    vec3 v = light_vec.xyz - p;
    float d2 = max(dot(v, v), 1e-12);
    dist = sqrt(d2);
    wi = v / dist;
    return light_power / d2;
}

#endif
