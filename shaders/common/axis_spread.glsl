// axis_spread.glsl — a coarse flyaway voxel's fiber axes: four axes on a cone about its
// tangent with its level-0 fibers' axis tensor (format 1.5, FLYAWAY_SPREAD), and a second
// group of four on a circular cone (format 1.8, FLYAWAY_GROUP; runtime/HYBRID_FORMAT.md
// §7.1 and §7.2; the module docs of the twin are the definition).
//
// Twin: runtime/src/brdf/axis_spread.rs (same names, same order):
//   e2 = cos(roll) r + sin(roll) q,  e3 = e1 x e2,  sin^2(delta) = l2 + l3,
//   axes cos(delta) e1 +- sin(delta) e2 (weight p/2 each), +- sin(delta) e3 ((1-p)/2),
//   p = l2 / (l2 + l3); (r, q) the branchless basis about +-e1 taken with z >= 0;
//   two groups: the first's four axes weighted by 1 - w, the second's (axis b, spread s:
//   l2 = l3 = s/2, roll 0) by w.
#ifndef AXIS_SPREAD_GLSL
#define AXIS_SPREAD_GLSL

#include "common/packing.glsl"

#define MAX_SPREAD_AXES 8

struct SpreadAxes {
    vec3 axes[MAX_SPREAD_AXES];
    float weights[MAX_SPREAD_AXES];
};

SpreadAxes single_axis(vec3 e1) {
    SpreadAxes s;
    for (int k = 0; k < MAX_SPREAD_AXES; ++k) {
        s.axes[k] = vec3(0.0);
        s.weights[k] = 0.0;
    }
    s.axes[0] = e1;
    s.weights[0] = 1.0;
    return s;
}

void spread_basis(vec3 e1, out vec3 r, out vec3 q) {
    vec3 e = e1.z < 0.0 ? -e1 : e1;
    float a = -1.0 / (1.0 + e.z);
    float b = e.x * e.y * a;
    r = vec3(1.0 + e.x * e.x * a, b, -e.x);
    q = vec3(b, 1.0 + e.y * e.y * a, -e.y);
}

SpreadAxes spread_axes(vec3 e1, float roll, float lambda2, float lambda3) {
    SpreadAxes s = single_axis(e1);
    float spread = min(lambda2 + lambda3, 1.0);
    if (!(spread > 0.0)) {
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
    s.weights[0] = p;
    s.weights[1] = p;
    s.weights[2] = 0.5 - p;
    s.weights[3] = 0.5 - p;
    return s;
}

// Two groups (format 1.8): first's four axes weighted by 1 - share, then second's four
// by share (clamped to [0, 1]; first alone where it is 0).
SpreadAxes grouped_axes(SpreadAxes first, SpreadAxes second, float share) {
    float w = min(max(share, 0.0), 1.0);
    if (!(w > 0.0)) {
        return first;
    }
    SpreadAxes s = first;
    for (int k = 0; k < 4; ++k) {
        s.weights[k] = first.weights[k] * (1.0 - w);
        s.axes[4 + k] = second.axes[k];
        s.weights[4 + k] = second.weights[k] * w;
    }
    return s;
}

// The second group: axis b (unit) on a circular cone of spread s = sin^2(delta).
SpreadAxes group_axes(vec3 b, float s) {
    float half_s = 0.5 * min(max(s, 0.0), 1.0);
    return spread_axes(b, 0.0, half_s, half_s);
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

// PackedAxisGroup as one word: the axis, octahedral 2 x snorm8 (bytes 0, 1), the share
// (byte 2) and the spread (byte 3), unorm8 (runtime/src/hybrid/flyaway.rs).
SpreadAxes packed_grouped_axes(vec3 e1, uint bits, uint group) {
    SpreadAxes first = packed_spread_axes(e1, bits);
    float share = float((group >> 16) & 0xffu) * (1.0 / 255.0);
    if (!(share > 0.0)) {
        return first;
    }
    vec3 b = octahedral_decode8(group);
    return grouped_axes(first, group_axes(b, float(group >> 24) * (1.0 / 255.0)), share);
}

#endif // AXIS_SPREAD_GLSL
