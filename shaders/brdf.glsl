// brdf.glsl — the cloth BRDF of the hybrid fabric model (Xu et al. 2019, Eqs. 1–3,
// read as DESIGN.md §5). Self-contained: include it anywhere (GLSL 4.50, no extensions).
//
// Twin: runtime/src/brdf/mod.rs has the same functions, with the same names, in the same
// order, and the same arithmetic. Change one, change the other. A test evaluates this
// file on the GPU (shaders/brdf_eval.comp) against the Rust twin for 131 072 random and
// extreme inputs (lavapipe: 99% agree within 1e-6 relative, all within 1e-4);
// shaders/brdf_test_vectors.json pins both for ports. Keep cloth_atan2: built-in
// asin/atan are vendor approximations that narrow lobes amplify.
//
// FRAME. A lobe lives in a shading frame (n, t, b = n x t): n the normal, t the fiber
// tangent (an axis: t and -t give the same value), in the same space as the directions
// (tile space for the hybrid model: x, y along the tile, z up, out of the cloth). All
// directions point AWAY from the surface: wi toward the light, wo toward the viewer.
//
// ANGLES (radians). For a unit direction w:
//   theta in [-pi/2, pi/2]: the angle from w to the normal plane, sin(theta) = dot(w, t);
//   phi in (-pi, pi]: the signed angle of w's projection in the normal plane, measured
//       from n: phi = atan(dot(w, b), dot(w, n)). Along t the projection vanishes and we
//       define phi = 0 (cos phi = 1).
// Mirror reflection about the normal plane has theta_o = -theta_i, so the lobes peak at
// theta_i + theta_o = 0, and fall off with phi_i + phi_o.
//
// THE BRDF (our bounded reading of Eqs. 1-3; the printed Eq. 2 has no beta_j and a width
// that shrinks without bound):
//   f_r = k_d + F(eta, cos theta_d) * max(cos phi_i, 0)^a * sum_j k_j * S_j
//   G(x; beta)  = exp(-x^2 / (2 beta^2)) / (sqrt(2 pi) beta)   (normalized over x)
//   P(x; gamma) = exp(-x^2 / (2 gamma^2));  P = 1 for gamma <= 0 ("gamma = infinity")
//   S_j = G(theta_i + theta_o; beta_j) * P(phi_i + phi_o; gamma_j)          reading 0, bounded
//   S_j = G(theta_i + theta_o; max(beta_j * P(phi_i + phi_o; gamma_j), BETA_MIN))  reading 1, width
//   S_j = G(theta_i + theta_o; w_j) * w_j / max(w_j, beta_j / HELD_RISE),
//         w_j = max(beta_j * P(phi_i + phi_o; gamma_j), BETA_MIN)                     reading 2, held
// The held reading (format 1.14) narrows as the width reading does but never rises above
// HELD_RISE times the lobe's peak G(0; beta_j); the width reading's peak grows as 1/P, up
// to 400 k_j. Where P >= 1 / HELD_RISE the two are the same.
// All readings live here and only here (cloth_lobe_shape); a model file records which one
// it was fitted with. F is the unpolarized dielectric Fresnel reflectance, fed with
// cos theta_d, theta_d = (theta_o - theta_i) / 2 (cloth_fresnel_cos: the one place where
// this is chosen; at the peak it equals the printed F(eta, theta_i)). max(cos phi_i, 0)^a
// is Sadeghi et al.'s shadowing term, with 0^0 = 1 (a = 0 switches it off).
//
// UNITS AND RANGES. k_d and k_j are linear RGB; k_d carries no 1/pi. Parameters are
// clamped before use, so any FINITE input gives a finite, non-negative result:
//   k_d, k_j in [0, 65504]; eta in [1, 4]; a in [0, 1e4]; beta in [1e-3, 1e4];
//   gamma <= 0 means off, else gamma in [1e-3, 1e4].
// Degenerate frames are completed deterministically (cloth_frame). Inputs must not be
// NaN (GLSL does not promise what min/max do with NaN); the model reader rejects NaN.
//
// WHAT A RENDERER OUTPUTS. Radiance toward wo under a light of irradiance E (perpendicular
// to the beam) from wi: E * f_r * max(dot(n, wi), 0) (cloth_response). cloth_lobe gives
// one lobe in its own frame, for texels whose lobes have different frames (coarse levels).

#ifndef CLOTH_BRDF_GLSL
#define CLOTH_BRDF_GLSL

#define CLOTH_MAX_LOBES 8
#define CLOTH_READING_BOUNDED 0u
#define CLOTH_READING_WIDTH 1u
#define CLOTH_READING_HELD 2u
#define CLOTH_DIFFUSE_LAMBERT 0u
#define CLOTH_DIFFUSE_LOMMEL_SEELIGER 1u

const float CLOTH_BETA_MIN = 1e-3;
const float CLOTH_HELD_RISE = 4.0;
const float CLOTH_BETA_MAX = 1e4;
const float CLOTH_GAMMA_MIN = 1e-3;
const float CLOTH_GAMMA_MAX = 1e4;
const float CLOTH_K_MAX = 65504.0;
const float CLOTH_ETA_MAX = 4.0;
const float CLOTH_A_MAX = 1e4;
const float CLOTH_EPS_LEN2 = 1e-20;  // below: a zero vector
const float CLOTH_EPS_PERP2 = 1e-8;  // t within 1e-4 of parallel to n: degenerate
const float CLOTH_EPS_PROJ2 = 1e-12; // projection on the normal plane vanishes: w along t
const float CLOTH_INV_SQRT_2PI = 0.3989423;

// One specular lobe: RGB strength k, theta width beta, phi falloff gamma (<= 0: off).
struct ClothLobe {
    vec3 k;
    float beta;
    float gamma;
};

// Eq. 1's parameters for lobes sharing one frame; the first lobe_count lobes are used.
struct ClothParams {
    vec3 kd;
    float eta;
    float a;
    uint lobe_count;
    ClothLobe lobes[CLOTH_MAX_LOBES];
};

struct ClothFrame {
    vec3 n;
    vec3 t;
    vec3 b;
};

struct ClothAngles {
    float sin_theta;
    float cos_theta;
    float theta;
    float phi;
    float cos_phi;
};

// A unit tangent perpendicular to unit n (Duff et al. 2017): completes degenerate frames,
// and is the reference from which packed tangents measure their angle.
vec3 cloth_reference_tangent(vec3 n) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float b = n.x * n.y * a;
    return vec3(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
}

// Orthonormal frame of normal n and tangent t (neither need be unit); t is made
// perpendicular to n (Gram-Schmidt, twice). Fallbacks: n ~ 0 -> +Z; t ~ 0 or t parallel to n -> reference tangent.
ClothFrame cloth_frame(vec3 n, vec3 t) {
    float n_len2 = dot(n, n);
    n = n_len2 > CLOTH_EPS_LEN2 ? n * (1.0 / sqrt(n_len2)) : vec3(0.0, 0.0, 1.0);
    float t_len2 = dot(t, t);
    t = t_len2 > CLOTH_EPS_LEN2 ? t * (1.0 / sqrt(t_len2)) : vec3(0.0);
    vec3 t_perp = t - n * dot(t, n);
    float perp2 = dot(t_perp, t_perp);
    if (perp2 > CLOTH_EPS_PERP2) {
        // A second Gram-Schmidt pass: the first leaves dot(n, t) ~ eps / sin(n, t) when t
        // is nearly parallel to n.
        vec3 t1 = t_perp * (1.0 / sqrt(perp2));
        vec3 t2 = t1 - n * dot(t1, n);
        t = t2 * (1.0 / sqrt(dot(t2, t2)));
    } else {
        t = cloth_reference_tangent(n);
    }
    ClothFrame f;
    f.n = n;
    f.t = t;
    f.b = cross(n, t);
    return f;
}

// The frame of a flyaway fiber seen from wo (DESIGN.md section 5): t = the fiber axis,
// n = wo made perpendicular to t (the fiber seen side-on), b = n x t. Fallbacks:
// fiber ~ 0 -> +X; wo parallel to t -> n = cloth_reference_tangent(t).
ClothFrame cloth_fiber_frame(vec3 fiber, vec3 wo) {
    float f_len2 = dot(fiber, fiber);
    vec3 t = f_len2 > CLOTH_EPS_LEN2 ? fiber * (1.0 / sqrt(f_len2)) : vec3(1.0, 0.0, 0.0);
    vec3 n_raw = wo - t * dot(wo, t);
    float n_len2 = dot(n_raw, n_raw);
    vec3 n = n_len2 > CLOTH_EPS_PROJ2 ? n_raw * (1.0 / sqrt(n_len2)) : cloth_reference_tangent(t);
    ClothFrame f;
    f.n = n;
    f.t = t;
    f.b = cross(n, t);
    return f;
}

// atan2(y, x) in (-pi, pi], computed the same way in both twins (Cephes' atanf on
// min/max of |x|, |y|, relative error ~2e-7): GPUs' built-in inverse trigonometry is an
// approximation of their own (lavapipe's asin is off by up to 3.9e-4 rad, its atan by
// 3e-6), which narrow lobes (beta ~ 0.005) amplify a hundredfold. atan2(0, 0) = 0; the
// sign of a zero y is ignored (atan2(-0, -1) = pi).
float cloth_atan2(float y, float x) {
    float ax = abs(x);
    float ay = abs(y);
    float hi = max(ax, ay);
    float lo = min(ax, ay);
    float r = hi > 0.0 ? lo / hi : 0.0;
    // r in [0, 1]; above tan(pi/8) reduce with atan r = pi/4 + atan((r - 1)/(r + 1)).
    float base = 0.0;
    if (r > 0.41421357) {
        base = 0.78539819;
        r = (r - 1.0) / (r + 1.0);
    }
    float z = r * r;
    float a = base + ((((8.0537445e-2 * z - 1.3877686e-1) * z + 1.9977711e-1) * z - 3.333295e-1) * z * r + r);
    if (ay > ax) {
        a = 1.5707964 - a;
    }
    if (x < 0.0) {
        a = 3.1415927 - a;
    }
    return y < 0.0 ? -a : a;
}

// theta and phi of unit direction w in frame f.
ClothAngles cloth_angles(ClothFrame f, vec3 w) {
    ClothAngles r;
    r.sin_theta = clamp(dot(w, f.t), -1.0, 1.0);
    r.cos_theta = sqrt(max(1.0 - r.sin_theta * r.sin_theta, 0.0));
    // theta = asin(sin theta), through the twins' own arctangent (see cloth_atan2).
    r.theta = cloth_atan2(r.sin_theta, r.cos_theta);
    float x = dot(w, f.n);
    float y = dot(w, f.b);
    float r2 = x * x + y * y;
    if (r2 > CLOTH_EPS_PROJ2) {
        r.phi = cloth_atan2(y, x);
        r.cos_phi = x * (1.0 / sqrt(r2));
    } else {
        r.phi = 0.0;
        r.cos_phi = 1.0;
    }
    return r;
}

// Unpolarized dielectric Fresnel reflectance, relative index eta, incidence cosine cos_i.
float cloth_fresnel(float eta, float cos_i) {
    eta = min(max(eta, 1.0), CLOTH_ETA_MAX);
    float c = min(max(cos_i, 0.0), 1.0);
    float sin2_t = (1.0 - c * c) / (eta * eta);
    float cos_t = sqrt(max(1.0 - sin2_t, 0.0));
    float rs = (c - eta * cos_t) / max(c + eta * cos_t, 1e-30);
    float rp = (eta * c - cos_t) / max(eta * c + cos_t, 1e-30);
    return 0.5 * (rs * rs + rp * rp);
}

// The cosine fed to the Fresnel term: cos theta_d, theta_d = (theta_o - theta_i) / 2,
// computed as sqrt((1 + cos(theta_o - theta_i)) / 2) since |theta_d| <= pi/2.
float cloth_fresnel_cos(ClothAngles wi, ClothAngles wo) {
    float cos_diff = wo.cos_theta * wi.cos_theta + wo.sin_theta * wi.sin_theta;
    return sqrt(max(0.5 * (1.0 + cos_diff), 0.0));
}

// max(cos phi_i, 0)^a with 0^0 = 1.
float cloth_shadowing(float cos_phi_i, float a) {
    a = min(max(a, 0.0), CLOTH_A_MAX);
    if (a <= 0.0) {
        return 1.0;
    }
    if (cos_phi_i <= 0.0) {
        return 0.0;
    }
    return pow(min(cos_phi_i, 1.0), a);
}

// G(x; beta), beta clamped to [BETA_MIN, BETA_MAX].
float cloth_gaussian(float x, float beta) {
    beta = min(max(beta, CLOTH_BETA_MIN), CLOTH_BETA_MAX);
    return exp(-(x * x) / (2.0 * beta * beta)) * (CLOTH_INV_SQRT_2PI / beta);
}

// P(x; gamma); 1 for gamma <= 0 (gamma = infinity).
float cloth_phi_falloff(float x, float gamma) {
    if (!(gamma > 0.0)) {
        return 1.0;
    }
    gamma = min(max(gamma, CLOTH_GAMMA_MIN), CLOTH_GAMMA_MAX);
    return exp(-(x * x) / (2.0 * gamma * gamma));
}

// The held reading's height factor for a lobe of width beta narrowed to w:
// w / max(w, beta / HELD_RISE) (1 where the lobe rises less than HELD_RISE times its peak).
float cloth_held_height(float beta, float w) {
    return w / max(beta / CLOTH_HELD_RISE, w);
}

// S_j at theta_i + theta_o = theta_sum, phi_i + phi_o = phi_sum: where the readings differ.
float cloth_lobe_shape(float theta_sum, float phi_sum, float beta, float gamma, uint reading) {
    if (reading == CLOTH_READING_WIDTH) {
        beta = min(max(beta, CLOTH_BETA_MIN), CLOTH_BETA_MAX);
        return cloth_gaussian(theta_sum, max(beta * cloth_phi_falloff(phi_sum, gamma), CLOTH_BETA_MIN));
    }
    if (reading == CLOTH_READING_HELD) {
        beta = min(max(beta, CLOTH_BETA_MIN), CLOTH_BETA_MAX);
        float w = max(beta * cloth_phi_falloff(phi_sum, gamma), CLOTH_BETA_MIN);
        return cloth_gaussian(theta_sum, w) * cloth_held_height(beta, w);
    }
    return cloth_gaussian(theta_sum, beta) * cloth_phi_falloff(phi_sum, gamma);
}

// sum_j k_j * S_j over the lobes in use (Eq. 2).
vec3 cloth_specular(ClothParams p, ClothAngles wi, ClothAngles wo, uint reading) {
    float theta_sum = wi.theta + wo.theta;
    float phi_sum = wi.phi + wo.phi;
    vec3 sum = vec3(0.0);
    uint count = min(p.lobe_count, uint(CLOTH_MAX_LOBES));
    for (uint j = 0u; j < count; ++j) {
        vec3 k = min(max(p.lobes[j].k, vec3(0.0)), vec3(CLOTH_K_MAX));
        sum += k * cloth_lobe_shape(theta_sum, phi_sum, p.lobes[j].beta, p.lobes[j].gamma, reading);
    }
    return sum;
}

// f_r(wi, wo) of Eq. 1 for lobes sharing frame f. RGB, finite, >= 0.
vec3 cloth_brdf(ClothParams p, ClothFrame f, vec3 wi, vec3 wo, uint reading) {
    ClothAngles ai = cloth_angles(f, wi);
    ClothAngles ao = cloth_angles(f, wo);
    vec3 kd = min(max(p.kd, vec3(0.0)), vec3(CLOTH_K_MAX));
    float fresnel = cloth_fresnel(p.eta, cloth_fresnel_cos(ai, ao));
    return kd + cloth_specular(p, ai, ao, reading) * (fresnel * cloth_shadowing(ai.cos_phi, p.a));
}

// One lobe in its own frame f with Eq. 1's Fresnel and shadowing factors, without k_d:
// F * max(cos phi_i, 0)^a * k * S. With a shared frame, k_d + sum_j cloth_lobe = cloth_brdf.
vec3 cloth_lobe(ClothLobe lobe, float eta, float a, ClothFrame f, vec3 wi, vec3 wo, uint reading) {
    ClothAngles ai = cloth_angles(f, wi);
    ClothAngles ao = cloth_angles(f, wo);
    float fresnel = cloth_fresnel(eta, cloth_fresnel_cos(ai, ao));
    vec3 k = min(max(lobe.k, vec3(0.0)), vec3(CLOTH_K_MAX));
    return k * (cloth_lobe_shape(ai.theta + ao.theta, ai.phi + ao.phi, lobe.beta, lobe.gamma, reading) * fresnel * cloth_shadowing(ai.cos_phi, a));
}

// cos(phi/2) from cos(phi), phi in (-pi, pi]: sqrt((1 + cos phi)/2), no trigonometry.
float cloth_half_cos(float cos_phi) {
    return sqrt(0.5 * (1.0 + min(max(cos_phi, -1.0), 1.0)));
}

// One lobe of a flyaway fibre under the cylinder law (format 1.11, MODEL flag bit 4),
// its cosine included: k S(theta_i + theta_o, 0) F(eta, cos theta_d) c^a cos theta_i c,
// c = cos(phi_i / 2), in the fibre frame seen from wo (phi_o = 0). The cylinder's
// reflecting normal bisects the light's and the viewer's azimuths about the axis.
vec3 cloth_cylinder_lobe(ClothLobe lobe, float eta, float a, ClothFrame f, vec3 wi, vec3 wo, uint reading) {
    ClothAngles ai = cloth_angles(f, wi);
    ClothAngles ao = cloth_angles(f, wo);
    float c = cloth_half_cos(ai.cos_phi);
    float fresnel = cloth_fresnel(eta, cloth_fresnel_cos(ai, ao));
    vec3 k = min(max(lobe.k, vec3(0.0)), vec3(CLOTH_K_MAX));
    return k * (cloth_lobe_shape(ai.theta + ao.theta, 0.0, lobe.beta, lobe.gamma, reading) * fresnel * cloth_shadowing(c, a) * ai.cos_theta * c);
}

// Outgoing radiance per unit irradiance, lobes sharing frame f: f_r * max(dot(n, wi), 0).
vec3 cloth_response(ClothParams p, ClothFrame f, vec3 wi, vec3 wo, uint reading) {
    return cloth_brdf(p, f, wi, wo, reading) * max(dot(f.n, wi), 0.0);
}

// The diffuse term's cosine factor about n (the texel's lobe-0 normal), by law:
// CLOTH_DIFFUSE_LAMBERT max(n.wi, 0); CLOTH_DIFFUSE_LOMMEL_SEELIGER
// max(n.wi, 0) * 2 / max(mu_i + mu_o, CLOTH_DIFFUSE_MU_MIN), mu = max(w.z, 0) the
// cosines to the tile's normal.
const float CLOTH_DIFFUSE_MU_MIN = 0.1;

float cloth_diffuse_cosine(uint law, vec3 n, vec3 wi, vec3 wo) {
    float cos_i = max(dot(n, wi), 0.0);
    if (law == CLOTH_DIFFUSE_LOMMEL_SEELIGER) {
        return cos_i * 2.0 / max(max(wi.z, 0.0) + max(wo.z, 0.0), CLOTH_DIFFUSE_MU_MIN);
    }
    return cos_i;
}

// The law under light uniform over the tile's upper hemisphere, relative to Lambert's,
// for n = z: 1, or 4 (1 - mu_o ln(1 + 1/mu_o)), mu_o = max(wo.z, 0) (4 at 0). The
// environment's diffuse term is k_d E(n) times this.
float cloth_diffuse_env_factor(uint law, vec3 wo) {
    if (law != CLOTH_DIFFUSE_LOMMEL_SEELIGER) {
        return 1.0;
    }
    float mu_o = max(wo.z, 0.0);
    return mu_o > 1e-6 ? 4.0 * (1.0 - mu_o * log(1.0 + 1.0 / mu_o)) : 4.0;
}

// A texel's visibility gradient (format 1.12): max(1 + g_o.(wo.x, wo.y) + g_i.(wi.x, wi.y), 0),
// g = (g_o.x, g_o.y, g_i.x, g_i.y) each clamped to +-CLOTH_GRADIENT_MAX; tile space, as
// mu of the diffuse law. What a texel on a yarn's flank shows more of from that side.
const float CLOTH_GRADIENT_MAX = 2.0;

float cloth_visibility_gradient(vec4 g, vec3 wi, vec3 wo) {
    vec4 c = min(max(g, vec4(-CLOTH_GRADIENT_MAX)), vec4(CLOTH_GRADIENT_MAX));
    return max(1.0 + c.x * wo.x + c.y * wo.y + c.z * wi.x + c.w * wi.y, 0.0);
}

// A texel's visibility curvature (format 1.15): the six second-order terms of the
// directions' slant, each even under wi <-> wo, and the visibility with them,
// max(1 + g.(wo.x, wo.y, wi.x, wi.y) + q.e(wi, wo), 0), each q clamped to
// +-CLOTH_CURVATURE_MAX. q = 0 is cloth_visibility_gradient.
const float CLOTH_CURVATURE_MAX = 2.0;

void cloth_curvature_terms(vec3 wi, vec3 wo, out vec3 e0, out vec3 e1) {
    e0 = vec3(wo.x * wo.x + wi.x * wi.x, wo.y * wo.y + wi.y * wi.y, wo.x * wo.y + wi.x * wi.y);
    e1 = vec3(wo.x * wi.x, wo.y * wi.y, wo.x * wi.y + wo.y * wi.x);
}

float cloth_visibility(vec4 g, vec3 q0, vec3 q1, vec3 wi, vec3 wo) {
    vec4 c = min(max(g, vec4(-CLOTH_GRADIENT_MAX)), vec4(CLOTH_GRADIENT_MAX));
    vec3 d0 = min(max(q0, vec3(-CLOTH_CURVATURE_MAX)), vec3(CLOTH_CURVATURE_MAX));
    vec3 d1 = min(max(q1, vec3(-CLOTH_CURVATURE_MAX)), vec3(CLOTH_CURVATURE_MAX));
    vec3 e0;
    vec3 e1;
    cloth_curvature_terms(wi, wo, e0, e1);
    float even = d0.x * e0.x + d0.y * e0.y + d0.z * e0.z + d1.x * e1.x + d1.y * e1.y + d1.z * e1.z;
    return max(1.0 + c.x * wo.x + c.y * wo.y + c.z * wi.x + c.w * wi.y + even, 0.0);
}

// THE TRANSMISSION TERM of a BSDF texel (format 1.3): diffuse kd and one lobe about the
// transmitted direction, attenuated along the slant path with optical depth tau. All
// zeros: nothing comes through.
#define CLOTH_TAU_MAX 16.0
#define CLOTH_TRANSMISSION_MU_MIN 0.05
#define CLOTH_OPENNESS_Q_MAX 64.0
// A texel's openness (format 1.10): O(mu_o) = o exp(-q (1/mu_o - 1)), the fraction of
// straight rays that cross it untouched (cloth_openness).
struct ClothOpenness {
    float o;
    float q;
    vec2 aniso;
};
// grad, q0, q1: the transmission's visibility, gradient (g_u, g_l) and curvature (q split
// as cloth_visibility's) (format 1.16; zero without).
struct ClothTransmission {
    vec3 kd;
    ClothLobe lobe;
    float tau;
    ClothOpenness gap;
    vec4 grad;
    vec3 q0;
    vec3 q1;
};

// (cos 2phi, sin 2phi) of w's azimuth in the tile: an axis's, (0, 0) straight up or down.
vec2 cloth_azimuth_axis(vec3 w) {
    float r2 = w.x * w.x + w.y * w.y;
    return r2 > 1e-12 ? vec2(w.x * w.x - w.y * w.y, 2.0 * w.x * w.y) / r2 : vec2(0.0);
}

// o exp(-q (1 + a cos 2phi + b sin 2phi) (1/mu_o - 1)), mu_o = |wo.z| clamped to
// [0.05, 1], phi wo's azimuth in the tile, o to [0, 1], q to [0, 64], a, b to [-1, 1],
// the azimuth factor to [0, 2]: the map behind the sheet seen through the gaps, per unit
// radiance.
float cloth_openness(ClothOpenness g, vec3 wo) {
    float o = min(max(g.o, 0.0), 1.0);
    float q = min(max(g.q, 0.0), CLOTH_OPENNESS_Q_MAX);
    float mo = min(max(abs(wo.z), CLOTH_TRANSMISSION_MU_MIN), 1.0);
    vec2 cs = cloth_azimuth_axis(wo);
    vec2 ab = min(max(g.aniso, vec2(-1.0)), vec2(1.0));
    float rate = min(max(1.0 + ab.x * cs.x + ab.y * cs.y, 0.0), 2.0);
    return o * exp(-q * rate * (1.0 / mo - 1.0));
}

// exp(-tau (1/mu_i + 1/mu_o - 2)), mu = |cos| to the tile normal clamped to [0.05, 1],
// tau to [0, 16]: 1 at normal incidence and view. Symmetric.
float cloth_transmission_attenuation(float tau, float mu_i, float mu_o) {
    float t = min(max(tau, 0.0), CLOTH_TAU_MAX);
    float mi = min(max(abs(mu_i), CLOTH_TRANSMISSION_MU_MIN), 1.0);
    float mo = min(max(abs(mu_o), CLOTH_TRANSMISSION_MU_MIN), 1.0);
    return exp(-t * (1.0 / mi + 1.0 / mo - 2.0));
}

// The transmission's visibility (format 1.16): max(1 + g_u . u.xy + g_l . l.xy + q . e(l, u), 0)
// with u the direction above the tile plane and l the one below, g clamped to +-2, q to
// +-2: cloth_visibility with the viewer's side above. Symmetric in (wi, wo).
float cloth_transmission_visibility(vec4 g, vec3 q0, vec3 q1, vec3 wi, vec3 wo) {
    vec3 upper = wi.z > 0.0 ? wi : wo;
    vec3 lower = wi.z > 0.0 ? wo : wi;
    return cloth_visibility(g, q0, q1, lower, upper);
}

// w mirrored through the tile plane (z -> -z).
vec3 cloth_mirror_z(vec3 w) {
    return vec3(w.x, w.y, -w.z);
}

// f_t(wi, wo) for directions on opposite sides of the tile plane (wi.z * wo.z < 0):
//   f_t = (k_dt + k_t * G(theta_l* + theta_u; beta_t) * P(phi_l* + phi_u; gamma_t)) * A(tau) * M_t
// u = whichever direction is above the plane, l* = the other mirrored through it, angles
// in frame f (the texel's lobe-0 frame); bounded shape, no Fresnel, no shadowing; M_t =
// cloth_transmission_visibility (format 1.16). Peaks straight through (wo = -wi for n = z)
// and is symmetric in (wi, wo). Same side: 0.
vec3 cloth_transmission(ClothTransmission t, ClothFrame f, vec3 wi, vec3 wo) {
    if (!(wi.z * wo.z < 0.0)) {
        return vec3(0.0);
    }
    vec3 upper = wi.z > 0.0 ? wi : wo;
    vec3 lower = wi.z > 0.0 ? wo : wi;
    ClothAngles au = cloth_angles(f, upper);
    ClothAngles al = cloth_angles(f, cloth_mirror_z(lower));
    vec3 kd = min(max(t.kd, vec3(0.0)), vec3(CLOTH_K_MAX));
    vec3 k = min(max(t.lobe.k, vec3(0.0)), vec3(CLOTH_K_MAX));
    return (kd + k * cloth_lobe_shape(al.theta + au.theta, al.phi + au.phi, t.lobe.beta, t.lobe.gamma, CLOTH_READING_BOUNDED)) * (cloth_transmission_attenuation(t.tau, wi.z, wo.z) * cloth_transmission_visibility(t.grad, t.q0, t.q1, wi, wo));
}

// Transmitted radiance per unit irradiance: f_t * |wi.z| (the tile's cosine).
vec3 cloth_transmission_response(ClothTransmission t, ClothFrame f, vec3 wi, vec3 wo) {
    return cloth_transmission(t, f, wi, wo) * abs(wi.z);
}

#endif // CLOTH_BRDF_GLSL
