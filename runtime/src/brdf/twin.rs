//! What the GLSL/Rust twin test shares: the GPU input and output records of
//! `shaders/brdf_eval.comp`, the generator of random and extreme inputs, the Rust
//! evaluation of one input, and the test-vector table `shaders/brdf_test_vectors.json`.
//!
//! The records are `#[repr(C)]` + `Pod` with the std430 layout of the compute shader
//! (16-byte vectors, no `Vec3`), sizes asserted at compile time.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::{
    BrdfReading, ClothLobe, ClothOpenness, ClothParams, ClothTransmission, DiffuseLaw, MAX_LOBES, cloth_brdf, cloth_cylinder_lobe, cloth_diffuse_cosine, cloth_diffuse_env_factor, cloth_fiber_frame, cloth_frame, cloth_lobe, cloth_openness, cloth_transmission_visibility,
    cloth_transmission, cloth_visibility, cloth_visibility_gradient,
};

/// One evaluation request, laid out as `EvalInput` in `shaders/brdf_eval.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BrdfEvalInput {
    /// Frame normal (xyz; w unused), not necessarily unit.
    pub n: [f32; 4],
    /// Frame tangent (xyz), not necessarily unit or perpendicular to n.
    pub t: [f32; 4],
    /// Direction toward the light (xyz), unit.
    pub wi: [f32; 4],
    /// Direction toward the viewer (xyz), unit.
    pub wo: [f32; 4],
    /// k_d (rgb) and η (w).
    pub kd_eta: [f32; 4],
    pub a: f32,
    /// [`BrdfReading`] as u32.
    pub reading: u32,
    pub lobe_count: u32,
    pub _pad: u32,
    /// Per lobe: k (rgb), β (w).
    pub lobe_k_beta: [[f32; 4]; MAX_LOBES],
    /// γ of lobe j at `[j / 4][j % 4]`.
    pub lobe_gamma: [[f32; 4]; MAX_LOBES / 4],
}

/// One evaluation result, laid out as `EvalOutput` in `shaders/brdf_eval.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BrdfEvalOutput {
    /// `cloth_brdf` (rgb); w = 0.
    pub brdf: [f32; 4],
    /// `cloth_lobe` of lobe 0 in the same frame (rgb); w = 0.
    pub lobe0: [f32; 4],
    /// `cloth_brdf` in `cloth_fiber_frame(t, wo)`: t read as a flyaway's fiber axis (rgb).
    pub fiber: [f32; 4],
    /// `cloth_cylinder_lobe` of lobe 0 in that fiber frame (rgb).
    pub cylinder: [f32; 4],
}

const _: () = assert!(core::mem::size_of::<BrdfEvalInput>() == 256);
const _: () = assert!(core::mem::size_of::<BrdfEvalOutput>() == 64);

impl BrdfEvalInput {
    pub fn new(n: Vec3, t: Vec3, wi: Vec3, wo: Vec3, p: &ClothParams, reading: BrdfReading) -> BrdfEvalInput {
        let mut input = BrdfEvalInput {
            n: n.extend(0.0).to_array(),
            t: t.extend(0.0).to_array(),
            wi: wi.extend(0.0).to_array(),
            wo: wo.extend(0.0).to_array(),
            kd_eta: p.kd.extend(p.eta).to_array(),
            a: p.a,
            reading: reading as u32,
            lobe_count: p.lobe_count.min(MAX_LOBES as u32),
            ..Default::default()
        };
        for (j, lobe) in p.lobes.iter().enumerate() {
            input.lobe_k_beta[j] = lobe.k.extend(lobe.beta).to_array();
            input.lobe_gamma[j / 4][j % 4] = lobe.gamma;
        }
        input
    }

    pub fn params(&self) -> ClothParams {
        let mut p = ClothParams { kd: v3(self.kd_eta), eta: self.kd_eta[3], a: self.a, lobe_count: self.lobe_count.min(MAX_LOBES as u32), ..Default::default() };
        for j in 0..MAX_LOBES {
            p.lobes[j] = ClothLobe { k: v3(self.lobe_k_beta[j]), beta: self.lobe_k_beta[j][3], gamma: self.lobe_gamma[j / 4][j % 4] };
        }
        p
    }

    pub fn reading(&self) -> BrdfReading {
        BrdfReading::from_u32(self.reading).unwrap_or_default()
    }

    /// What `shaders/brdf_eval.comp` computes for this input, in Rust.
    pub fn evaluate(&self) -> BrdfEvalOutput {
        let p = self.params();
        let f = cloth_frame(v3(self.n), v3(self.t));
        let (wi, wo) = (v3(self.wi), v3(self.wo));
        let brdf = cloth_brdf(&p, &f, wi, wo, self.reading());
        let lobe0 = cloth_lobe(&p.lobes[0], p.eta, p.a, &f, wi, wo, self.reading());
        let ff = cloth_fiber_frame(v3(self.t), wo);
        let fiber = cloth_brdf(&p, &ff, wi, wo, self.reading());
        let cylinder = cloth_cylinder_lobe(&p.lobes[0], p.eta, p.a, &ff, wi, wo, self.reading());
        BrdfEvalOutput { brdf: brdf.extend(0.0).to_array(), lobe0: lobe0.extend(0.0).to_array(), fiber: fiber.extend(0.0).to_array(), cylinder: cylinder.extend(0.0).to_array() }
    }
}

fn v3(a: [f32; 4]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

/// SplitMix64: a tiny deterministic generator, enough for test inputs.
#[derive(Clone, Debug)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next_f32()
    }

    /// Log-uniform in [lo, hi], lo > 0.
    pub fn log_range(&mut self, lo: f32, hi: f32) -> f32 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.next_f32()).exp()
    }

    /// Uniform on the unit sphere.
    pub fn unit_vector(&mut self) -> Vec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f32::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

fn random_params(rng: &mut SplitMix64) -> ClothParams {
    let count = 1 + (rng.next_u64() % MAX_LOBES as u64) as usize;
    let lobes: Vec<ClothLobe> = (0..count)
        .map(|_| ClothLobe {
            k: Vec3::new(rng.range(0.0, 4.0), rng.range(0.0, 4.0), rng.range(0.0, 4.0)),
            beta: rng.log_range(0.005, 1.0),
            gamma: if rng.next_f32() < 0.2 { ClothLobe::GAMMA_OFF } else { rng.log_range(0.02, 3.0) },
        })
        .collect();
    let kd = Vec3::new(rng.range(0.0, 0.5), rng.range(0.0, 0.5), rng.range(0.0, 0.5));
    ClothParams::new(kd, rng.range(1.0, 2.5), rng.range(0.0, 8.0), &lobes)
}

/// Mirror of `w` about the normal plane of `t` (θ ↦ −θ), rotated about t by a small
/// random angle so that φ_i + φ_o stays near 0, i.e. near the lobes' peak.
fn near_specular(rng: &mut SplitMix64, n: Vec3, t: Vec3, wi: Vec3) -> Vec3 {
    let f = cloth_frame(n, t);
    let (x, y, z) = (wi.dot(f.n), wi.dot(f.b), wi.dot(f.t));
    let jitter = rng.range(-0.3, 0.3);
    let phi = -y.atan2(x) + jitter;
    let r = (x * x + y * y).sqrt();
    let dtheta = rng.range(-0.1, 0.1);
    let w = f.n * (r * phi.cos()) + f.b * (r * phi.sin()) - f.t * z + f.t * dtheta;
    w.normalize_or(f.n)
}

/// The extreme inputs: directions along t, n, b and grazing the normal plane,
/// degenerate frames, and zero or huge parameters, in all combinations.
pub fn extreme_inputs() -> Vec<BrdfEvalInput> {
    let frames = [
        (Vec3::Z, Vec3::X),
        (Vec3::ZERO, Vec3::X),
        (Vec3::Z, Vec3::ZERO),
        (Vec3::Z, Vec3::Z),
        (Vec3::Z, -Vec3::Z),
        (Vec3::new(0.0, 0.0, 5.0), Vec3::new(0.001, 0.0, 3.0)),
        (Vec3::new(0.0, 0.0, -1.0), Vec3::Y),
        (Vec3::new(1e-12, 0.0, 0.0), Vec3::new(0.0, 1e12, 0.0)),
    ];
    let g = 1e-7f32;
    let dirs = [
        Vec3::X,
        -Vec3::X,
        Vec3::Z,
        -Vec3::Z,
        Vec3::Y,
        Vec3::new((1.0 - g * g).sqrt(), 0.0, g),
        Vec3::new(0.0, (1.0f32 - 1e-6).sqrt(), 1e-3),
        Vec3::new(0.6, 0.0, 0.8),
        Vec3::new(-0.6, 0.0, 0.8),
    ];
    let lobe_sets: [&[ClothLobe]; 6] = [
        &[ClothLobe { k: Vec3::ONE, beta: 0.1, gamma: 0.5 }, ClothLobe { k: Vec3::splat(0.5), beta: 0.3, gamma: 0.0 }],
        &[ClothLobe { k: Vec3::ONE, beta: 0.0, gamma: 1e-9 }],
        &[ClothLobe { k: Vec3::splat(1e30), beta: 1e-6, gamma: -1.0 }],
        &[ClothLobe { k: Vec3::splat(65504.0), beta: 1e30, gamma: 1e30 }],
        &[ClothLobe { k: Vec3::ZERO, beta: 0.05, gamma: 0.05 }; 8],
        &[],
    ];
    let scalars = [(1.5f32, 0.0f32), (1.0, 1.0), (0.0, 100.0), (100.0, 1e30), (1.33, 0.5)];
    let mut out = Vec::new();
    for (fi, &(n, t)) in frames.iter().enumerate() {
        for (ii, &wi) in dirs.iter().enumerate() {
            for (oi, &wo) in dirs.iter().enumerate() {
                // Every pair for the plain frame; a rotating subset for the others.
                let which = fi + ii + oi;
                let (eta, a) = scalars[which % scalars.len()];
                let lobes = lobe_sets[(which / 2) % lobe_sets.len()];
                let kd = if which % 3 == 0 { Vec3::splat(1e30) } else { Vec3::new(0.2, 0.1, 0.05) };
                let p = ClothParams::new(kd, eta, a, lobes);
                for reading in [BrdfReading::Bounded, BrdfReading::Width, BrdfReading::Held] {
                    out.push(BrdfEvalInput::new(n, t, wi, wo, &p, reading));
                }
            }
        }
    }
    out
}

/// `count` inputs: first [`extreme_inputs`], then random ones (half of them near the
/// specular configuration, where the lobes are large), deterministic in `seed`.
pub fn generate_inputs(count: usize, seed: u64) -> Vec<BrdfEvalInput> {
    let mut out = extreme_inputs();
    out.truncate(count);
    let mut rng = SplitMix64(seed);
    while out.len() < count {
        let n = if rng.next_f32() < 0.8 { (Vec3::Z + 0.6 * rng.unit_vector()).normalize_or(Vec3::Z) } else { rng.unit_vector() };
        let t = rng.unit_vector();
        let wi = rng.unit_vector();
        let wo = if rng.next_f32() < 0.5 { near_specular(&mut rng, n, t, wi) } else { rng.unit_vector() };
        let p = random_params(&mut rng);
        let reading = match rng.next_u64() % 3 {
            0 => BrdfReading::Bounded,
            1 => BrdfReading::Width,
            _ => BrdfReading::Held,
        };
        out.push(BrdfEvalInput::new(n, t, wi, wo, &p, reading));
    }
    out
}

/// One row of `shaders/brdf_test_vectors.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TestVector {
    pub n: [f32; 3],
    pub t: [f32; 3],
    pub wi: [f32; 3],
    pub wo: [f32; 3],
    pub kd: [f32; 3],
    pub eta: f32,
    pub a: f32,
    /// "bounded", "width" or "held".
    pub reading: String,
    pub lobes: Vec<TestVectorLobe>,
    /// `cloth_brdf(params, cloth_frame(n, t), wi, wo, reading)`.
    pub brdf: [f32; 3],
    /// `cloth_lobe(lobes[0], eta, a, cloth_frame(n, t), wi, wo, reading)`.
    pub lobe0: [f32; 3],
    /// `cloth_brdf(params, cloth_fiber_frame(t, wo), wi, wo, reading)`.
    pub fiber: [f32; 3],
    /// `cloth_cylinder_lobe(lobes[0], eta, a, cloth_fiber_frame(t, wo), wi, wo, reading)`
    /// (format 1.11's flyaway lobes).
    pub cylinder: [f32; 3],
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TestVectorLobe {
    pub k: [f32; 3],
    pub beta: f32,
    pub gamma: f32,
}

/// One row of the file's second table: the per-texel factors around the BRDF that a
/// renderer multiplies in (brdf.glsl's visibility, diffuse laws, openness and
/// transmission), for one pair of directions.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShadingVector {
    /// The texel's frame (as `TestVector`'s: `cloth_frame(n, t)` completes it).
    pub n: [f32; 3],
    pub t: [f32; 3],
    pub wi: [f32; 3],
    pub wo: [f32; 3],
    /// Visibility gradient (g_o,x, g_o,y, g_i,x, g_i,y) and curvature (format 1.15's order).
    pub g: [f32; 4],
    pub q: [f32; 6],
    /// Openness (o, q, a, b).
    pub openness: [f32; 4],
    /// Transmission: k_dt, k_t, β_t, γ_t, τ, in the frame (n, t).
    pub kdt: [f32; 3],
    pub kt: [f32; 3],
    pub beta_t: f32,
    pub gamma_t: f32,
    pub tau: f32,
    /// The transmission's visibility (format 1.16): gradient (g_u,x, g_u,y, g_l,x, g_l,y)
    /// and curvature (format 1.15's order).
    pub g_t: [f32; 4],
    pub q_t: [f32; 6],
    /// `cloth_visibility_gradient(g, wi, wo)`.
    pub visibility_gradient: f32,
    /// `cloth_visibility(g, q, wi, wo)` (GLSL: q split as q0 = q[0..3], q1 = q[3..6]).
    pub visibility: f32,
    /// `cloth_diffuse_cosine(law, normalize(n), wi, wo)`, Lambert then Lommel–Seeliger.
    pub diffuse_cosine: [f32; 2],
    /// `cloth_diffuse_env_factor(LOMMEL_SEELIGER, wo)`.
    pub diffuse_env_factor: f32,
    /// `cloth_openness(openness, wo)`.
    pub openness_value: f32,
    /// `cloth_transmission_visibility(g_t, q_t, wi, wo)`.
    pub transmission_visibility: f32,
    /// `cloth_transmission(transmission, cloth_frame(n, t), wi, wo)` (with g_t, q_t).
    pub transmission: [f32; 3],
}

impl ShadingVector {
    /// The row for these inputs (the openness is `tr.gap`), its outputs evaluated by the
    /// Rust twin.
    pub fn evaluate(n: Vec3, t: Vec3, wi: Vec3, wo: Vec3, g: [f32; 4], q: [f32; 6], tr: ClothTransmission) -> ShadingVector {
        let gap = tr.gap;
        let nn = n.normalize_or(Vec3::Z);
        ShadingVector {
            n: n.to_array(),
            t: t.to_array(),
            wi: wi.to_array(),
            wo: wo.to_array(),
            g,
            q,
            openness: [gap.o, gap.q, gap.aniso[0], gap.aniso[1]],
            kdt: tr.kd.to_array(),
            kt: tr.lobe.k.to_array(),
            beta_t: tr.lobe.beta,
            gamma_t: tr.lobe.gamma,
            tau: tr.tau,
            g_t: tr.grad,
            q_t: tr.curv,
            visibility_gradient: cloth_visibility_gradient(g, wi, wo),
            visibility: cloth_visibility(g, q, wi, wo),
            diffuse_cosine: [cloth_diffuse_cosine(DiffuseLaw::Lambert, nn, wi, wo), cloth_diffuse_cosine(DiffuseLaw::LommelSeeliger, nn, wi, wo)],
            diffuse_env_factor: cloth_diffuse_env_factor(DiffuseLaw::LommelSeeliger, wo),
            openness_value: cloth_openness(&gap, wo),
            transmission_visibility: cloth_transmission_visibility(tr.grad, tr.curv, wi, wo),
            transmission: cloth_transmission(&tr, &cloth_frame(n, t), wi, wo).to_array(),
        }
    }

    /// The same inputs evaluated again (what the table check compares).
    pub fn reevaluate(&self) -> ShadingVector {
        let v = |a: [f32; 3]| Vec3::from_array(a);
        let gap = ClothOpenness { o: self.openness[0], q: self.openness[1], aniso: [self.openness[2], self.openness[3]] };
        let tr = ClothTransmission { kd: v(self.kdt), lobe: ClothLobe { k: v(self.kt), beta: self.beta_t, gamma: self.gamma_t }, tau: self.tau, gap, grad: self.g_t, curv: self.q_t };
        ShadingVector::evaluate(v(self.n), v(self.t), v(self.wi), v(self.wo), self.g, self.q, tr)
    }

    /// The outputs, in one list.
    pub fn outputs(&self) -> Vec<f32> {
        let mut o = vec![self.visibility_gradient, self.visibility, self.diffuse_cosine[0], self.diffuse_cosine[1], self.diffuse_env_factor, self.openness_value, self.transmission_visibility];
        o.extend(self.transmission);
        o
    }
}

/// The shading table: edge cases (straight up, grazing, coefficients past their clamps,
/// directions on one side or across the sheet) and 40 random rows.
pub fn shading_vectors() -> Vec<ShadingVector> {
    let mut rng = SplitMix64(0x5ad1_0067);
    let mut rows = Vec::new();
    let tr0 = ClothTransmission { kd: Vec3::new(0.2, 0.1, 0.05), lobe: ClothLobe { k: Vec3::splat(0.8), beta: 0.2, gamma: 0.6 }, tau: 0.5, gap: ClothOpenness::default(), grad: [0.4, -0.3, 0.5, 0.2], curv: [0.3, -0.2, 0.1, 0.5, -0.4, 0.2] };
    let gap0 = ClothOpenness { o: 0.3, q: 2.0, aniso: [0.5, -0.25] };
    let (g0, q0) = ([0.5, -0.3, 0.2, 0.4], [0.3, -0.2, 0.1, 0.6, -0.4, 0.2]);
    let up = Vec3::Z;
    let slant = Vec3::new(0.6, 0.0, 0.8);
    let grazing = Vec3::new(0.0, 0.999_999_5, 0.001);
    let below = Vec3::new(-0.3, 0.2, -0.932_737_9);
    let edges: [(Vec3, Vec3, [f32; 4], [f32; 6]); 8] = [
        (up, up, g0, q0),
        (slant, slant, g0, q0),
        (grazing, slant, g0, q0),
        (slant, grazing, g0, q0),
        (slant, below, g0, q0),
        (below, slant, g0, q0),
        (slant, Vec3::new(-0.6, 0.0, 0.8), [5.0, -5.0, 5.0, -5.0], [9.0, -9.0, 9.0, -9.0, 9.0, -9.0]),
        (Vec3::new(0.8, 0.0, 0.6), Vec3::new(0.8, 0.0, 0.6), [-2.0, 0.0, -2.0, 0.0], [0.0; 6]),
    ];
    for (wi, wo, g, q) in edges {
        rows.push(ShadingVector::evaluate(Vec3::new(0.1, -0.2, 1.0), Vec3::X, wi, wo, g, q, ClothTransmission { gap: gap0, ..tr0 }));
    }
    // Parameters past their clamps: openness and τ.
    let wild_gap = ClothOpenness { o: 2.0, q: 100.0, aniso: [3.0, -3.0] };
    let wild_tr = ClothTransmission { kd: Vec3::splat(-1.0), lobe: ClothLobe { k: Vec3::splat(1e6), beta: 0.1, gamma: ClothLobe::GAMMA_OFF }, tau: 50.0, gap: wild_gap, grad: [5.0, -5.0, 5.0, -5.0], curv: [9.0, -9.0, 9.0, -9.0, 9.0, -9.0] };
    rows.push(ShadingVector::evaluate(Vec3::Z, Vec3::Y, slant, below, g0, q0, wild_tr));
    for _ in 0..40 {
        let n = rng.unit_vector() * 0.5 + Vec3::Z;
        let t = rng.unit_vector();
        let wi = rng.unit_vector();
        let wo = if rng.next_f32() < 0.5 { rng.unit_vector() } else { Vec3::new(-wi.x, -wi.y, -wi.z) * 0.9 + rng.unit_vector() * 0.1 };
        let wo = wo.normalize_or(Vec3::Z);
        let g = std::array::from_fn(|_| rng.range(-2.5, 2.5));
        let q = std::array::from_fn(|_| rng.range(-2.5, 2.5));
        let gap = ClothOpenness { o: rng.range(0.0, 1.0), q: rng.log_range(0.01, 80.0), aniso: [rng.range(-1.2, 1.2), rng.range(-1.2, 1.2)] };
        let lobe = ClothLobe { k: Vec3::new(rng.range(0.0, 2.0), rng.range(0.0, 2.0), rng.range(0.0, 2.0)), beta: rng.log_range(0.02, 1.0), gamma: if rng.next_f32() < 0.2 { ClothLobe::GAMMA_OFF } else { rng.log_range(0.05, 3.0) } };
        let grad = std::array::from_fn(|_| rng.range(-2.5, 2.5));
        let curv = std::array::from_fn(|_| rng.range(-2.5, 2.5));
        let tr = ClothTransmission { kd: Vec3::new(rng.range(0.0, 0.5), rng.range(0.0, 0.5), rng.range(0.0, 0.5)), lobe, tau: rng.range(0.0, 4.0), gap, grad, curv };
        rows.push(ShadingVector::evaluate(n, t, wi, wo, g, q, tr));
    }
    rows
}

/// The file of test vectors: a header saying what it is, and the rows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TestVectorFile {
    pub about: String,
    pub vectors: Vec<TestVector>,
    /// The per-texel factors around the BRDF ([`ShadingVector`]).
    pub shading: Vec<ShadingVector>,
}

impl TestVectorFile {
    /// JSON with one vector per line, for readable diffs.
    pub fn to_json(&self) -> String {
        let rows: Vec<String> = self.vectors.iter().map(|v| serde_json::to_string(v).unwrap_or_default()).collect();
        let shading: Vec<String> = self.shading.iter().map(|v| serde_json::to_string(v).unwrap_or_default()).collect();
        let about = serde_json::to_string(&self.about).unwrap_or_default();
        format!("{{\n\"about\": {about},\n\"vectors\": [\n{}\n],\n\"shading\": [\n{}\n]}}\n", rows.join(",\n"), shading.join(",\n"))
    }
}

impl TestVector {
    pub fn from_input(input: &BrdfEvalInput) -> TestVector {
        let p = input.params();
        let out = input.evaluate();
        let a3 = |v: [f32; 4]| [v[0], v[1], v[2]];
        TestVector {
            n: a3(input.n),
            t: a3(input.t),
            wi: a3(input.wi),
            wo: a3(input.wo),
            kd: p.kd.to_array(),
            eta: p.eta,
            a: p.a,
            reading: input.reading().name().to_string(),
            lobes: p.lobes().iter().map(|l| TestVectorLobe { k: l.k.to_array(), beta: l.beta, gamma: l.gamma }).collect(),
            brdf: a3(out.brdf),
            lobe0: a3(out.lobe0),
            fiber: a3(out.fiber),
            cylinder: a3(out.cylinder),
        }
    }
}

/// The table: a sample of the extreme inputs and 48 random ones, small enough to read.
pub fn test_vector_file() -> TestVectorFile {
    let extremes = extreme_inputs();
    let mut rows: Vec<TestVector> = extremes.iter().step_by(37).map(TestVector::from_input).collect();
    let random = generate_inputs(extremes.len() + 48, 0x7e57_7ec7);
    rows.extend(random[extremes.len()..].iter().map(TestVector::from_input));
    TestVectorFile {
        about: "Test vectors of the cloth BRDF (shaders/brdf.glsl and runtime/src/brdf/mod.rs), written by the Rust twin. \
                Each row: frame (n, t; not necessarily unit or orthogonal: cloth_frame completes it), wi (toward the light) and \
                wo (toward the viewer), parameters, reading, and the outputs cloth_brdf, cloth_lobe(lobe 0), cloth_brdf in cloth_fiber_frame(t, wo) and cloth_cylinder_lobe(lobe 0) in that frame. \
                The GLSL agrees with these to 1e-4 relative on lavapipe (99% of 131072 inputs within 1e-6); a port should too, using cloth_atan2 rather than its own asin/atan. \
                The second table, shading, holds the factors a renderer multiplies in around the BRDF, per texel: cloth_visibility_gradient and cloth_visibility \
                (gradient g, curvature q), cloth_diffuse_cosine for both laws (n normalized) and cloth_diffuse_env_factor (Lommel-Seeliger), cloth_openness and cloth_transmission \
                (frame cloth_frame(n, t)), including directions across the sheet and parameters past their clamps. \
                Regenerate with FABRIC_BLESS=1 cargo test -p fabric-runtime brdf_test_vectors."
            .into(),
        vectors: rows,
        shading: shading_vectors(),
    }
}
