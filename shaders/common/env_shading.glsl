// env_shading.glsl — environment light of a hit: each lobe as a small mixture of
// spherical Gaussians, read in a few grouped lookups of the prefiltered environment (paper §7.2,
// "Extensions"; runtime/HYBRID_FORMAT.md §6).
//
// Twin: runtime/src/cpu/env_shading.rs (env_erf, env_theta_cells, lobe_env_nodes,
// texel_env_response, transmission_env_diffuse_factor, transmission_env_response; the
// module docs there are the definition); the lookups are
// common/env_lookup.glsl. Included only by programs that define
// HYBRID_ENV (hybrid.comp): binding 11 holds the levels, params.env_* say where.
#ifndef ENV_SHADING_GLSL
#define ENV_SHADING_GLSL

#include "common/env_lookup.glsl"

// EnvBudget: SGs and lookups per lobe, on the surface and on a flyaway.
#define ENV_NODES 16u
#define ENV_LOOKUPS 4u
#define ENV_FLYAWAY_NODES 8u
#define ENV_FLYAWAY_LOOKUPS 1u

// erf, Abramowitz & Stegun 7.1.26.
float env_erf(float x) {
    float s = x < 0.0 ? -1.0 : 1.0;
    x = abs(x);
    float t = 1.0 / (1.0 + 0.3275911 * x);
    float y = 1.0 - (((((1.061405429 * t - 1.453152027) * t) + 1.421413741) * t - 0.284496736) * t + 0.254829592) * t * exp(-x * x);
    return s * y;
}

// One theta cell of a lobe's band (ThetaCell): centroid sin and cos, mass of G, Fresnel
// there, its share of the SG's width.
struct ThetaCell {
    float s;
    float c;
    float mass;
    float fresnel;
    float sigma;
};

// env_theta_cells: the k_theta cells of theta_c +- 3 beta' within [-pi/2, pi/2].
void env_theta_cells(float theta_c, float beta_eff, uint k_theta, ClothAngles ao, float eta, out ThetaCell cells[4]) {
    for (uint i = 0u; i < 4u; ++i) {
        cells[i] = ThetaCell(0.0, 0.0, 0.0, 0.0, 0.0);
    }
    const float HALF_PI = 1.57079632679490;
    float lo = max(theta_c - 3.0 * beta_eff, -HALF_PI);
    float hi = min(theta_c + 3.0 * beta_eff, HALF_PI);
    if (!(hi > lo)) {
        return;
    }
    float d_theta = (hi - lo) / float(k_theta);
    float inv = 1.0 / (beta_eff * 1.41421356237310);
    float e0 = env_erf((lo - theta_c) * inv);
    float g0 = cloth_gaussian(lo - theta_c, beta_eff);
    // To the constant 4 (k_theta's most), the cells past k_theta skipped: a loop of a
    // known count is unrolled, and unrolled it does not count against lavapipe's budget
    // of 65535 loop iterations per invocation (runtime/GPU_MEASUREMENTS.md, "lavapipe's
    // loop budget"). The arithmetic is the same, in the same order.
    for (uint i = 0u; i < 4u; ++i) {
        float t0 = lo + float(i) * d_theta;
        float t1 = lo + float(i + 1u) * d_theta;
        float e1 = env_erf((t1 - theta_c) * inv);
        float g1 = cloth_gaussian(t1 - theta_c, beta_eff);
        float mass = 0.5 * (e1 - e0);
        if (i < k_theta && mass > 1e-7) {
            float theta = clamp(theta_c + beta_eff * beta_eff * (g0 - g1) / mass, t0, t1);
            float st = sin(theta);
            float ct = cos(theta);
            float cos_diff = ao.cos_theta * ct + ao.sin_theta * st;
            float fresnel = cloth_fresnel(eta, sqrt(max(0.5 * (1.0 + cos_diff), 0.0)));
            cells[i] = ThetaCell(st, ct, mass, fresnel, min(beta_eff, 0.4 * d_theta));
        }
        e0 = e1;
        g0 = g1;
    }
}

// SGs merged into one lookup (EnvGroup): summed weight, mean axis and sigma^2 weighted
// by the weights' RGB mean, plus their spread 1 - |sum w a|^2 / (sum w)^2.
struct EnvGroup {
    vec3 weight;
    vec3 axis;
    float lum;
    float sigma2;
};

void env_group_add(inout EnvGroup g, vec3 axis, vec3 weight, float sigma) {
    float l = (weight.x + weight.y + weight.z) * (1.0 / 3.0);
    g.weight += weight;
    g.axis += axis * l;
    g.lum += l;
    g.sigma2 += l * sigma * sigma;
}

// The visibility gradient g and curvature q at the group's mean direction
// (EnvGroup::mean_axis).
float env_group_gradient(EnvGroup g, vec4 grad, vec3 q0, vec3 q1, vec3 wo) {
    vec3 mean_axis = g.lum > 0.0 ? g.axis * (1.0 / g.lum) : vec3(0.0);
    return cloth_visibility(grad, q0, q1, mean_axis, wo);
}

// The group's lookup; the group emptied.
vec3 env_group_flush(inout EnvGroup g) {
    vec3 r = vec3(0.0);
    if (g.lum > 0.0) {
        float len2 = dot(g.axis, g.axis);
        float spread = max(1.0 - len2 / (g.lum * g.lum), 0.0);
        float sigma = sqrt(g.sigma2 / g.lum + spread);
        r = g.weight * env_blurred(g.axis * (1.0 / sqrt(max(len2, 1e-30))), sigma);
    }
    g = EnvGroup(vec3(0.0), vec3(0.0), 0.0, 0.0);
    return r;
}

// One lobe's SG mixture of at most `nodes` SGs, read from the prefiltered map in at most
// `lookups` groups (lobe_env_nodes, EnvGroup, EnvBudget). `through`: the transmission
// lobe of attenuation `tau` under the map below the sheet (EnvSide::Transmitted; the
// bounded reading, no Fresnel or shadowing, axes mirrored), else a reflection lobe;
// `cylinder`: a flyaway's lobe under the cylinder law (EnvSide::Cylinder: the whole
// circle of azimuths, shadowing and cosine at cos(phi/2), no falloff). Each group's
// lookup is scaled by the visibility gradient `grad` and curvature (q0, q1) at its mean
// direction.
vec3 lobe_env(ClothLobe lobe, float eta, float a, ClothFrame f, vec3 wo, uint reading, bool volumetric, bool through, float tau, bool cylinder, uint nodes, uint lookups, vec4 grad, vec3 q0, vec3 q1) {
    vec3 k = min(max(lobe.k, vec3(0.0)), vec3(CLOTH_K_MAX));
    if (max(max(k.x, k.y), k.z) <= 0.0) {
        return vec3(0.0);
    }
    if (through || cylinder) {
        reading = CLOTH_READING_BOUNDED;
        volumetric = false;
    }
    ClothAngles ao = cloth_angles(f, wo);
    float theta_c = -ao.theta;
    float beta = min(max(lobe.beta, CLOTH_BETA_MIN), CLOTH_BETA_MAX);
    bool falloff_on = reading == CLOTH_READING_BOUNDED && lobe.gamma > 0.0 && !cylinder;
    const float HALF_PI = 1.57079632679490;
    float phi_lo = cylinder ? -ENV_PI : -HALF_PI;
    float phi_hi = cylinder ? ENV_PI : HALF_PI;
    if (falloff_on) {
        float g3 = 3.0 * lobe.gamma;
        phi_lo = max(phi_lo, -ao.phi - g3);
        phi_hi = min(phi_hi, -ao.phi + g3);
    }
    if (!(phi_hi > phi_lo)) {
        return vec3(0.0);
    }
    float theta_ext = min(6.0 * beta, ENV_PI);
    float phi_arc = max((phi_hi - phi_lo) * cos(theta_c), 1e-4);
    nodes = max(nodes, 1u);
    lookups = max(lookups, 1u);
    uint k_theta = uint(clamp(round(sqrt(float(nodes) * theta_ext / phi_arc)), 1.0, float(min(4u, max(nodes / 2u, 1u)))));
    uint k_phi = max(nodes / k_theta, 1u);
    float d_phi = (phi_hi - phi_lo) / float(k_phi);
    uint per_group = (k_theta * k_phi + lookups - 1u) / lookups;
    uint emitted = 0u;
    EnvGroup group = EnvGroup(vec3(0.0), vec3(0.0), 0.0, 0.0);
    bool bounded = reading == CLOTH_READING_BOUNDED;
    // The bounded reading's theta cells are the same in every phi column: computed once.
    ThetaCell cells[4];
    if (bounded) {
        env_theta_cells(theta_c, beta, k_theta, ao, eta, cells);
    }
    vec3 sum = vec3(0.0);
    for (uint c = 0u; c < k_phi; ++c) {
        float phi = phi_lo + (float(c) + 0.5) * d_phi;
        float sp = sin(phi);
        float cp = cos(phi);
        float pf = cylinder ? 1.0 : cloth_phi_falloff(phi + ao.phi, lobe.gamma);
        float cs = cylinder ? cloth_half_cos(cp) : cp;
        // The width and held readings fold P into beta' (the held reading's height
        // cloth_held_height, as well).
        float beta_eff = max(beta * pf, CLOTH_BETA_MIN);
        float height = bounded ? pf : (reading == CLOTH_READING_HELD ? cloth_held_height(beta, beta_eff) : 1.0);
        vec3 r_phi = k * ((through ? 1.0 : cloth_shadowing(cs, a)) * height);
        if (max(max(r_phi.x, r_phi.y), r_phi.z) <= 0.0) {
            continue;
        }
        if (!bounded) {
            env_theta_cells(theta_c, beta_eff, k_theta, ao, eta, cells);
        }
        // To the constant 4, as env_theta_cells (cells past k_theta have no mass).
        for (uint i = 0u; i < 4u; ++i) {
            ThetaCell cell = cells[i];
            vec3 wi = f.t * cell.s + (f.n * cp + f.b * sp) * cell.c;
            float cos_n = cell.c * cs;
            // Through the cloth: R = k_t P A(tau; w'.z, wo.z) w'.z, read at w' mirrored.
            vec3 r = through ? r_phi * (cloth_transmission_attenuation(tau, wi.z, wo.z) * wi.z) : r_phi * (cell.fresnel * cos_n * (volumetric ? volume_factor(wi, wo) : 1.0));
            vec3 weight = r * (cell.mass * d_phi * cell.c);
            if (i < k_theta && cell.mass > 0.0 && cos_n > 0.0 && wi.z > 0.0 && max(max(weight.x, weight.y), weight.z) > 0.0) {
                float sigma = max(cell.sigma, 0.4 * d_phi * cell.c);
                env_group_add(group, through ? cloth_mirror_z(wi) : wi, weight, sigma);
                emitted += 1u;
                if (emitted % per_group == 0u) {
                    float m = env_group_gradient(group, grad, q0, q1, wo);
                    sum += m * env_group_flush(group);
                }
            }
        }
    }
    float m = env_group_gradient(group, grad, q0, q1, wo);
    sum += m * env_group_flush(group);
    return sum;
}

// texel_env_response: k_d E(n_0) V_f(n_0) H(n_0, wo) + the lobes' SG mixtures (H the
// diffuse law's cloth_diffuse_env_factor), the texel edited by `e` as texel_response
// edits it.
vec3 texel_env_response(TexelRef r, Edit e, bool rotate, vec3 wo, uint reading, bool volumetric, uint diffuse, uint nodes, uint lookups) {
    EditedTexel t = edited_texel(r, e, rotate);
    vec4 grad = texel_gradient(r);
    vec3 q0;
    vec3 q1;
    texel_curvature(r, q0, q1);
    vec3 resp = vec3(0.0);
    if (max(max(t.kd.x, t.kd.y), t.kd.z) > 0.0) {
        // The gradient at the cosine lobe's mean direction, (2/3) n_0.
        float m = cloth_visibility(grad, q0, q1, t.n0 * (2.0 / 3.0), wo);
        resp = t.kd * env_irradiance(t.n0) * ((volumetric ? volume_factor(t.n0, wo) : 1.0) * cloth_diffuse_env_factor(diffuse, wo) * m);
    }
    for (uint j = 0u; j < t.count; ++j) {
        ClothFrame f;
        ClothLobe lobe = edited_lobe(r, e, t, j, f);
        resp += lobe_env(lobe, t.eta, t.a, f, wo, reading, volumetric, false, 0.0, r.cylinder, nodes, lookups, grad, q0, q1);
    }
    return resp;
}

// transmission_env_diffuse_factor: c(tau) = 1 - tau + tau^2 e^tau E1(tau), e^tau E1 by
// Abramowitz & Stegun 5.1.53 (tau < 1) and 5.1.56.
float transmission_env_diffuse_factor(float tau) {
    float t = min(max(tau, 0.0), CLOTH_TAU_MAX);
    if (!(t > 0.0)) {
        return 1.0;
    }
    float ex_e1;
    if (t < 1.0) {
        float e1 = -0.57721566 - log(t) + t * (0.99999193 + t * (-0.24991055 + t * (0.05519968 + t * (-0.00976004 + t * 0.00107857))));
        ex_e1 = exp(t) * e1;
    } else {
        float num = (((t + 8.5733287) * t + 18.059017) * t + 8.634761) * t + 0.26777373;
        float den = (((t + 9.573322) * t + 25.632956) * t + 21.099653) * t + 3.958497;
        ex_e1 = num / (den * t);
    }
    return max(1.0 - t + t * t * ex_e1, 0.0);
}

// transmission_env_response of the texel's transmission term, edited
// (edited_transmission): the map below the sheet through the cloth toward wo.
vec3 texel_env_transmission(TexelRef r, Edit e, bool rotate, vec3 wo, uint nodes, uint lookups) {
    ClothTransmission t;
    ClothFrame f;
    if (!(wo.z > 0.0) || !edited_transmission(r, e, rotate, t, f)) {
        return vec3(0.0);
    }
    vec3 kd = min(max(t.kd, vec3(0.0)), vec3(CLOTH_K_MAX));
    vec3 resp = vec3(0.0);
    if (max(max(kd.x, kd.y), kd.z) > 0.0) {
        // The transmission visibility at the lower cosine lobe's mean direction, -(2/3) z.
        float m = cloth_transmission_visibility(t.grad, t.q0, t.q1, vec3(0.0, 0.0, -2.0 / 3.0), wo);
        resp = kd * env_irradiance_full(vec3(0.0, 0.0, -1.0)) * (transmission_env_diffuse_factor(t.tau) * cloth_transmission_attenuation(t.tau, 1.0, wo.z) * m);
    }
    // The map seen straight through the gaps along the view ray (format 1.10).
    float gap = cloth_openness(t.gap, wo);
    if (gap > 0.0) {
        resp += gap * env_blurred(-wo, 0.0);
    }
    // Each group scaled by the transmission's visibility at its mean direction, which
    // lies below the sheet (mirrored axes): cloth_visibility reads g_u at wo and g_l
    // there, as cloth_transmission_visibility does.
    return resp + lobe_env(t.lobe, 1.0, 0.0, f, wo, CLOTH_READING_BOUNDED, false, true, t.tau, false, nodes, lookups, t.grad, t.q0, t.q1);
}

#endif // ENV_SHADING_GLSL
