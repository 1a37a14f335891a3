// axis_spread.glsl — a coarse flyaway voxel's fiber axes: four axes on a cone about its
// tangent with its level-0 fibers' axis tensor (format 1.5, FLYAWAY_SPREAD;
// runtime/HYBRID_FORMAT.md §7.1; the module docs of the twin are the definition).
//
// Twin: runtime/src/brdf/axis_spread.rs (same names, same order):
//   e2 = cos(roll) r + sin(roll) q,  e3 = e1 x e2,  sin^2(delta) = l2 + l3,
//   axes cos(delta) e1 +- sin(delta) e2 (weight p/2 each), +- sin(delta) e3 ((1-p)/2),
//   p = l2 / (l2 + l3); (r, q) the branchless basis about +-e1 taken with z >= 0.
#ifndef AXIS_SPREAD_GLSL
#define AXIS_SPREAD_GLSL

struct SpreadAxes {
    vec3 axes[4];
    vec4 weights;
};

void spread_basis(vec3 e1, out vec3 r, out vec3 q) {
    vec3 e = e1.z < 0.0 ? -e1 : e1;
    float a = -1.0 / (1.0 + e.z);
    float b = e.x * e.y * a;
    r = vec3(1.0 + e.x * e.x * a, b, -e.x);
    q = vec3(b, 1.0 + e.y * e.y * a, -e.y);
}

SpreadAxes spread_axes(vec3 e1, float roll, float lambda2, float lambda3) {
    SpreadAxes s;
    float spread = min(lambda2 + lambda3, 1.0);
    if (!(spread > 0.0)) {
        s.axes[0] = e1;
        s.axes[1] = vec3(0.0);
        s.axes[2] = vec3(0.0);
        s.axes[3] = vec3(0.0);
        s.weights = vec4(1.0, 0.0, 0.0, 0.0);
        return s;
    }
    vec3 r;
    vec3 q;
    spread_basis(e1, r, q);
    vec3 e2 = r * cos(roll) + q * sin(roll);
    vec3 e3 = cross(e1, e2);
    float sn = sqrt(spread);
    float c = sqrt(1.0 - spread);
    float p = 0.5 * (lambda2 / (lambda2 + lambda3));
    vec3 along = e1 * c;
    s.axes[0] = along + e2 * sn;
    s.axes[1] = along - e2 * sn;
    s.axes[2] = along + e3 * sn;
    s.axes[3] = along - e3 * sn;
    s.weights = vec4(p, p, 0.5 - p, 0.5 - p);
    return s;
}

// PackedAxisSpread's first word: roll unorm16 over [0, pi) in the low half, then the
// unorm8 weights l2, l3 (runtime/src/hybrid/flyaway.rs; the second word is the depth
// range flyaways.glsl reads).
SpreadAxes packed_spread_axes(vec3 e1, uint bits) {
    float roll = float(bits & 0xffffu) * (3.14159265358979 / 65536.0);
    float lambda2 = float((bits >> 16) & 0xffu) * (1.0 / 255.0);
    float lambda3 = float(bits >> 24) * (1.0 / 255.0);
    return spread_axes(e1, roll, lambda2, lambda3);
}

#endif // AXIS_SPREAD_GLSL
