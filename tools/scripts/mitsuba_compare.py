#!/usr/bin/env python3
"""Agreement and speed of `fabric reference` against Mitsuba 3 on the same .vol input.

How to run (from the repository root):

    pip install mitsuba numpy                     # Mitsuba 3 (scalar_rgb runs as is)
    apt-get install libllvm19                     # optional: enables llvm_ad_rgb
    cargo build --release -p fabric-tools         # the binary under test
    python3 tools/scripts/mitsuba_compare.py agree            # ~5 min on 2 cores
    python3 tools/scripts/mitsuba_compare.py bench            # paths/s, side by side

`agree` renders a small procedural woven fabric (or --fabric DIR) from several views
(orthographic and perspective cameras, directional and point lights, an environment
map, full multiple scattering, single scattering, nearest lookup) with both renderers, twice each with
independent seeds, and checks
  - image means within 1% (|mean_ours / mean_mitsuba - 1| < 0.01), and
  - per-pixel differences within the noise: RMS(ours - mitsuba) is compared with
    sqrt(noise_ours^2 + noise_mitsuba^2), each noise estimated from the difference of
    that renderer's two independent renders (E|A1 - A2|^2 = 2 noise^2); the ratio must
    be below 1.15 (it is ~1 when neither renderer is biased).
It exits non-zero if any check fails and writes a JSON report with --json.

`bench` renders the default twill (256x256x48: `fabric gen twill` output via --fabric,
or the script's own procedural twill of that size) from a few views and prints paths
per second of both renderers, measured on the same machine in the same run, and the
ratio. Mitsuba's time covers `mi.render` only (scene loading excluded); ours is the
render loop only (as `fabric reference --json` reports it).

Scene mapping (docs/DESIGN.md section 8; everything else is identical):
  - volume: `heterogeneous` medium inside a `cube` with a `null` BSDF that spans the
    .vol bounding box; sigma_t = gridvolume(density.vol), albedo = gridvolume(albedo.vol),
    scale = material.toml density_scale, phase = `sggx` with S = gridvolume(S.vol), the
    6 channels (xx, yy, zz, xy, xz, yz) of S = I - (1 - sigma^2) w_f w_f^T computed per
    voxel from orientation.vol; every gridvolume has use_grid_bbox = true, raw = true and
    filter_type = our --lookup;
  - camera: `look_at(origin, target, up)`; orthographic to_world = look_at . scale(extent/2),
    perspective fov = --fov with fov_axis = "x"; film with a box reconstruction filter;
  - lights: `directional` with direction = -(--light-dir) and irradiance = --irradiance;
    `point` with position = --point-light and intensity = --intensity;
  - environment (views with "envmap"): `envmap` with filename = --envmap, scale =
    --envmap-scale and to_world = rotate([0, 0, 1], --envmap-rotate) . rotate([1, 0, 0], 90)
    (the map's Y up becomes our Z up); the map the script writes is smooth at the texel
    scale, since Mitsuba interpolates it bilinearly and we look up the nearest texel;
  - integrator: `volpath` with max_depth = --max-depth (-1 when unlimited), rr_depth 5.
"""

import argparse
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]


# ----------------------------------------------------------------------------- volumes

def write_vol(path, data, bbox):
    """Mitsuba .vol, version 3, f32. data: (z, y, x, c) array."""
    nz, ny, nx, c = data.shape
    with open(path, "wb") as f:
        f.write(b"VOL" + bytes([3]))
        f.write(struct.pack("<iiiii", 1, nx, ny, nz, c))
        f.write(struct.pack("<6f", *bbox[0], *bbox[1]))
        f.write(np.ascontiguousarray(data, dtype="<f4").tobytes())


def read_vol(path):
    """Reads a .vol (f32 or f16 encodings) as (data (z, y, x, c) f32, bbox)."""
    raw = Path(path).read_bytes()
    if raw[:3] != b"VOL" or raw[3] != 3:
        raise SystemExit(f"{path}: not a version-3 .vol file")
    enc, nx, ny, nz, c = struct.unpack("<iiiii", raw[4:24])
    bbox = struct.unpack("<6f", raw[24:48])
    dtype = {1: "<f4", 2: "<f2"}.get(enc)
    if dtype is None:
        raise SystemExit(f"{path}: encoding {enc} is not supported by this script (f32 or f16)")
    data = np.frombuffer(raw[48:], dtype=dtype).astype(np.float32).reshape(nz, ny, nx, c)
    return data, (bbox[:3], bbox[3:])


def procedural_weave(nx, ny, nz, seed=1, twill=True):
    """A small woven fabric: warp yarns along x and weft yarns along y whose centre
    lines undulate in z (a 2/1 twill shift or plain weave), Gaussian density falloff
    from the yarn axis, fiber direction = yarn tangent plus a little random twist.
    Every voxel, empty or not, has a unit orientation (so S is defined everywhere)."""
    rng = np.random.default_rng(seed)
    pitch = max(nx // 8, 4)
    x = np.arange(nx) + 0.5
    y = np.arange(ny) + 0.5
    z = np.arange(nz) + 0.5
    Z, Y, X = np.meshgrid(z, y, x, indexing="ij")
    zc, amp = 0.5 * nz, 0.2 * nz
    r_h, r_v = 0.45 * pitch, 0.22 * nz
    density = np.zeros((nz, ny, nx), np.float32)
    tangent = np.zeros((nz, ny, nx, 3), np.float32)
    albedo = np.zeros((nz, ny, nx, 3), np.float32)
    shift = 1 if twill else 0
    for family in (0, 1):
        along, across = (X, Y) if family == 0 else (Y, X)
        k = np.floor(across / pitch)
        centre = (k + 0.5) * pitch
        phase = np.pi * (k * (1 + shift) + family)
        w = np.pi / pitch
        zline = zc + amp * np.cos(w * along + phase) * (1 if family == 0 else -1)
        dz = -amp * w * np.sin(w * along + phase) * (1 if family == 0 else -1)
        d2 = ((across - centre) / r_h) ** 2 + ((Z - zline) / r_v) ** 2
        rho = np.where(d2 < 1.0, np.exp(-1.5 * d2), 0.0).astype(np.float32)
        t = np.zeros((nz, ny, nx, 3), np.float32)
        t[..., family] = 1.0
        t[..., 2] = dz
        t += 0.15 * rng.standard_normal(t.shape).astype(np.float32)
        t /= np.linalg.norm(t, axis=-1, keepdims=True)
        take = rho > density
        density = np.where(take, rho, density)
        tangent = np.where(take[..., None], t, tangent)
        col = np.array([0.85, 0.65, 0.4] if family == 0 else [0.45, 0.6, 0.9], np.float32)
        albedo = np.where(take[..., None], col, albedo)
    empty = density <= 0
    tangent[empty] = np.array([1.0, 0.0, 0.0], np.float32)
    albedo[empty] = 0.5
    return density, albedo, tangent


def write_fabric(dirpath, density, albedo, orientation, bbox, density_scale, roughness):
    d = Path(dirpath)
    d.mkdir(parents=True, exist_ok=True)
    write_vol(d / "density.vol", density[..., None], bbox)
    write_vol(d / "albedo.vol", albedo, bbox)
    write_vol(d / "orientation.vol", orientation, bbox)
    (d / "material.toml").write_text(f"density_scale = {density_scale}\nroughness = {roughness}\n")


def read_material(dirpath):
    m = {"density_scale": 1.0, "roughness": 0.1}
    p = Path(dirpath) / "material.toml"
    if p.exists():
        for line in p.read_text().splitlines():
            line = line.split("#")[0].strip()
            if line.startswith("["):
                break
            if "=" in line:
                k, v = (s.strip() for s in line.split("=", 1))
                if k in m:
                    m[k] = float(v)
    return m


def prepare_mitsuba_inputs(fabric, out):
    """Writes the f32 grids and S.vol Mitsuba reads; returns (paths, bbox, material)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    mat = read_material(fabric)
    rho, bbox = read_vol(Path(fabric) / "density.vol")
    alb, _ = read_vol(Path(fabric) / "albedo.vol")
    ori, _ = read_vol(Path(fabric) / "orientation.vol")
    n = np.linalg.norm(ori, axis=-1, keepdims=True)
    # Our loader packs a zero orientation as +Z (octahedral fallback): do the same.
    f = np.where(n > 1e-6, ori / np.maximum(n, 1e-30), np.array([0, 0, 1], np.float32))
    k = 1.0 - mat["roughness"] ** 2
    S = np.stack([1 - k * f[..., 0] ** 2, 1 - k * f[..., 1] ** 2, 1 - k * f[..., 2] ** 2,
                  -k * f[..., 0] * f[..., 1], -k * f[..., 0] * f[..., 2], -k * f[..., 1] * f[..., 2]], -1)
    # Empty voxels contribute S = I whatever they store (our EmptyOrientation default,
    # baker/src/reference/medium.rs), so trilinear S near a fiber's edge matches ours.
    S[rho[..., 0] <= 0.0] = np.array([1, 1, 1, 0, 0, 0], np.float32)
    paths = {"density": out / "density.vol", "albedo": out / "albedo.vol", "S": out / "S.vol"}
    write_vol(paths["density"], rho, bbox)
    write_vol(paths["albedo"], np.clip(alb, 0, 1), bbox)
    write_vol(paths["S"], S.astype(np.float32), bbox)
    return paths, bbox, mat, rho.shape[:3][::-1]


# ----------------------------------------------------------------------------- Mitsuba's SGGX sampling
#
# Mitsuba 3 (checked with 3.9.1) samples its `sggx` phase function from the wrong
# distribution: `sggx_sample_vndf` projects S into the frame as B S B^T instead of
# B^T S B (an extra transpose; mitsuba-renderer/mitsuba3 issue #1728), so phase-sampled
# directions do not follow its own `eval_pdf` for anisotropic S (measured: for a fiber
# along y, sigma = 0.3 and w_i = (0, -0.85, 0.52), the mean sampled w_o is
# (0, 0.13, -0.66) where its eval integrates to (0, 0.65, 0.19)). Evaluation, projected
# area and next-event estimation are right, so single scattering agrees, but multiple
# scattering does not. `sggx_fixed` below is the same phase function with the sample
# computed in the frame basis (S_kj = e_k^T S e_j, as in Heitz et al. 2015's
# supplemental); it is the default for the comparison (`--phase native` uses Mitsuba's).
# Python plugins are traced into the JIT kernels of the llvm variants, so the default
# variant is llvm_ad_rgb.


def define_fixed_sggx(mi, dr):
  class SggxFixed(mi.PhaseFunction):
      """Mitsuba's sggx with the VNDF sample computed in the frame basis (S_kj = e_k^T S e_j)."""
      def __init__(self, props):
          mi.PhaseFunction.__init__(self, props)
          self.S = props['S']
          self.m_flags = mi.PhaseFunctionFlags.Anisotropic | mi.PhaseFunctionFlags.Microflake
      def _s(self, mei, active):
          return self.S.eval_6(mei, active)
      def projected_area(self, mei, active=True):
          return mi.sggx_projected_area(mei.wi, self._s(mei, active))
      def max_projected_area(self):
          return 1.0
      def eval_pdf(self, ctx, mei, wo, active=True):
          s = self._s(mei, active)
          pdf = 0.25 * mi.sggx_pdf(dr.normalize(wo + mei.wi), s) / mi.sggx_projected_area(mei.wi, s)
          return mi.Spectrum(pdf), pdf
      def sample(self, ctx, mei, sample1, sample2, active=True):
          s = self._s(mei, active)
          f = mei.sh_frame
          def q(a, b):
              return (a.x*b.x*s[0] + a.y*b.y*s[1] + a.z*b.z*s[2] + (a.x*b.y + a.y*b.x)*s[3] + (a.x*b.z + a.z*b.x)*s[4] + (a.y*b.z + a.z*b.y)*s[5])
          kk, jj, ii = q(f.s, f.s), q(f.t, f.t), q(f.n, f.n)
          kj, ki, ji = q(f.s, f.t), q(f.s, f.n), q(f.t, f.n)
          det = dr.abs(kk*jj*ii - kj*kj*ii - ki*ki*jj - ji*ji*kk + 2*kj*ki*ji)
          inv = dr.rsqrt(dr.maximum(ii, 1e-30))
          tmp = dr.sqrt(dr.maximum(jj*ii - ji*ji, 1e-30))
          mk = mi.Vector3f(dr.sqrt(det)/tmp, 0, 0)
          mj = mi.Vector3f(-inv*(ki*ji - kj*ii)/tmp, inv*tmp, 0)
          mii = inv*mi.Vector3f(ki, ji, ii)
          uvw = mi.warp.square_to_cosine_hemisphere(sample2)
          m = dr.normalize(uvw.x*mk + uvw.y*mj + uvw.z*mii)
          n = f.to_world(m)
          wo = dr.normalize(mi.reflect(mei.wi, n))
          pdf = 0.25 * mi.sggx_pdf(n, s) / mi.sggx_projected_area(mei.wi, s)
          return wo, mi.Spectrum(1.0), pdf
      def to_string(self):
          return 'SggxFixed'
  mi.register_phase('sggx_fixed', lambda props: SggxFixed(props))


# ----------------------------------------------------------------------------- scenes

def direction_from_angles(theta, phi):
    t, p = np.radians(theta), np.radians(phi)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


def resolve_view(view, bbox):
    """Fills origin/target/up/extent for --view-angles the way `fabric` does."""
    v = dict(view)
    lo, hi = np.array(bbox[0]), np.array(bbox[1])
    if "view_angles" in v:
        th, ph = v["view_angles"]
        centre = 0.5 * (lo + hi)
        top = np.array([centre[0], centre[1], hi[2]])
        radius = 0.5 * np.linalg.norm(hi - lo)
        v["target"] = top
        v["origin"] = top + (2 * radius + 1) * direction_from_angles(th, ph)
        ct, st = np.cos(np.radians(th)), np.sin(np.radians(th))
        cp, sp = np.cos(np.radians(ph)), np.sin(np.radians(ph))
        v["up"] = np.array([-ct * cp, -ct * sp, st])
        v.setdefault("extent", float(hi[0] - lo[0]))
    if "light_angles" in v:
        v["light_dir"] = direction_from_angles(*v["light_angles"])
    return v


def fabric_flags(v):
    fmt = lambda a: ",".join(f"{float(c):.9g}" for c in a)
    flags = ["--origin", fmt(v["origin"]), "--target", fmt(v["target"]), "--up", fmt(v["up"])]
    flags += ["--extent", f"{v['extent']:.9g}"] if "extent" in v else ["--fov", f"{v['fov']:.9g}"]
    if "envmap" in v:
        flags += ["--envmap", str(v["envmap"]), "--envmap-rotate", f"{v.get('envmap_rotate', 0.0):.9g}", "--envmap-scale", f"{v.get('envmap_scale', 1.0):.9g}"]
    elif "point_light" in v:
        flags += ["--point-light", fmt(v["point_light"]), "--intensity", f"{v.get('intensity', 1.0):.9g}"]
    else:
        flags += ["--light-dir", fmt(v["light_dir"]), "--irradiance", f"{v.get('irradiance', 1.0):.9g}"]
    if v.get("max_depth"):
        flags += ["--max-depth", str(v["max_depth"])]
    flags += ["--lookup", v.get("lookup", "trilinear")]
    return flags


def mitsuba_scene(mi, v, inputs, bbox, mat, width, height, spp):
    T = mi.ScalarTransform4f
    lo, hi = np.array(bbox[0]), np.array(bbox[1])
    look = T().look_at(origin=list(map(float, v["origin"])), target=list(map(float, v["target"])), up=list(map(float, v["up"])))
    film = {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"}, "pixel_format": "rgb"}
    sampler = {"type": "independent", "sample_count": spp}
    if "extent" in v:
        sensor = {"type": "orthographic", "to_world": look @ T().scale([v["extent"] / 2, v["extent"] / 2, 1.0]), "film": film, "sampler": sampler,
                  "near_clip": 1e-3, "far_clip": 1e5}
    else:
        sensor = {"type": "perspective", "to_world": look, "fov": float(v["fov"]), "fov_axis": "x", "film": film, "sampler": sampler,
                  "near_clip": 1e-3, "far_clip": 1e5}
    if "envmap" in v:
        emitter = {"type": "envmap", "filename": str(v["envmap"]), "scale": float(v.get("envmap_scale", 1.0)),
                   "to_world": T().rotate([0, 0, 1], float(v.get("envmap_rotate", 0.0))) @ T().rotate([1, 0, 0], 90.0)}
    elif "point_light" in v:
        emitter = {"type": "point", "position": list(map(float, v["point_light"])), "intensity": {"type": "rgb", "value": float(v.get("intensity", 1.0))}}
    else:
        emitter = {"type": "directional", "direction": list(map(float, -np.asarray(v["light_dir"]))), "irradiance": {"type": "rgb", "value": float(v.get("irradiance", 1.0))}}
    filt = v.get("lookup", "trilinear")
    grid = lambda p: {"type": "gridvolume", "filename": str(p), "use_grid_bbox": True, "raw": True, "filter_type": filt}
    medium = {"type": "heterogeneous", "sigma_t": grid(inputs["density"]), "albedo": grid(inputs["albedo"]), "scale": float(mat["density_scale"]),
              "phase": {"type": v.get("phase", "sggx_fixed"), "S": grid(inputs["S"])}}
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    cube = {"type": "cube", "to_world": T().translate(list(map(float, centre))) @ T().scale(list(map(float, half))), "bsdf": {"type": "null"}, "interior": medium}
    depth = v.get("max_depth") or -1
    return {"type": "scene", "integrator": {"type": "volpath", "max_depth": int(depth), "rr_depth": 5}, "sensor": sensor, "emitter": emitter, "fabric": cube}


def render_mitsuba(mi, scene_dict, spp, seed):
    scene = mi.load_dict(scene_dict)
    t = time.perf_counter()
    img = mi.render(scene, spp=spp, seed=seed)
    arr = np.array(img, dtype=np.float64)
    return arr[..., :3], time.perf_counter() - t


def fabric_binary(arg):
    if arg:
        return arg
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    exe = target / "release" / "fabric"
    if not exe.exists():
        raise SystemExit(f"{exe} not found: run `cargo build --release -p fabric-tools` (or pass --bin)")
    return str(exe)


def read_exr(path):
    """Reads our EXR through Mitsuba's bitmap reader."""
    import mitsuba as mi
    return np.array(mi.Bitmap(str(path)), dtype=np.float64)[..., :3]


def render_fabric(binary, fabric, v, width, height, spp, seed, out, extra=()):
    cmd = [binary, "reference", str(fabric), *fabric_flags(v), "--size", f"{width}x{height}", "--spp", str(spp), "--seed", str(seed), "--out", str(out), "--json", *extra]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"fabric reference failed:\n{' '.join(cmd)}\n{res.stdout}{res.stderr}")
    report = json.loads(res.stdout.strip().splitlines()[-1])
    return read_exr(out), report


# ----------------------------------------------------------------------------- commands

AGREE_VIEWS = [
    {"name": "ortho-top-directional", "view_angles": (0.0, 0.0), "light_angles": (35.0, -60.0)},
    {"name": "ortho-oblique-directional", "view_angles": (50.0, 30.0), "light_angles": (40.0, 200.0)},
    {"name": "ortho-mirror-directional", "view_angles": (45.0, 0.0), "light_angles": (45.0, 180.0)},
    {"name": "ortho-oblique-single", "view_angles": (40.0, 120.0), "light_angles": (30.0, 0.0), "max_depth": 2},
    {"name": "ortho-oblique-nearest", "view_angles": (40.0, 120.0), "light_angles": (30.0, 0.0), "lookup": "nearest"},
    {"name": "ortho-backlit-transmission", "view_angles": (160.0, 30.0), "light_angles": (30.0, 0.0)},
    {"name": "persp-point", "origin": (0.5, -0.9, 0.9), "target": (0.5, 0.5, 0.05), "up": (0, 0, 1), "fov": 45.0, "point_light": (0.9, -0.2, 0.8), "intensity": 1.0},
    {"name": "persp-directional", "origin": (-0.6, 0.3, 0.8), "target": (0.5, 0.5, 0.05), "up": (0, 0, 1), "fov": 50.0, "light_angles": (60.0, 90.0)},
    {"name": "ortho-point", "view_angles": (30.0, -90.0), "point_light": (0.2, 0.5, 0.6), "intensity": 0.5},
    {"name": "ortho-oblique-envmap", "view_angles": (50.0, 30.0), "envmap": "ENV", "envmap_rotate": 30.0},
    {"name": "ortho-oblique-envmap-single", "view_angles": (40.0, 120.0), "envmap": "ENV", "envmap_rotate": -75.0, "max_depth": 2},
    {"name": "persp-envmap", "origin": (-0.6, 0.3, 0.8), "target": (0.5, 0.5, 0.05), "up": (0, 0, 1), "fov": 50.0, "envmap": "ENV", "envmap_scale": 2.0},
]


def write_envmap(path, width=256, height=128):
    """A map with no symmetry that would hide a wrong orientation: a sky gradient, a
    colour ramp in azimuth (fading at the poles) and a bright blob (sigma 12 deg) toward local (theta 55, phi 70),
    smooth at the texel scale (Mitsuba filters bilinearly, we look up the nearest texel)."""
    import mitsuba as mi
    v, u = np.meshgrid((np.arange(height) + 0.5) / height, (np.arange(width) + 0.5) / width, indexing="ij")
    theta, phi = v * np.pi, u * 2 * np.pi
    d = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], -1)
    bt, bp = np.radians(55.0), np.radians(70.0)
    b = np.array([np.sin(bt) * np.sin(bp), np.cos(bt), -np.sin(bt) * np.cos(bp)])
    ang = np.arccos(np.clip(d @ b, -1, 1))
    blob = 6.0 * np.exp(-0.5 * (ang / np.radians(12.0)) ** 2)
    up = np.clip(d[..., 1], 0, 1)
    # Azimuthal terms fade at the poles (times sin theta), so the map is continuous there.
    st = np.sin(theta)
    img = np.stack([0.2 + 0.3 * up + 0.1 * st * np.sin(phi), 0.25 + 0.2 * up + 0.1 * st * np.cos(phi), 0.15 + 0.4 * up], -1) + blob[..., None] * np.array([1.0, 0.8, 0.5])
    mi.Bitmap(img.astype(np.float32)).write(str(path))
    return path


def small_fabric(tmp, dims=(48, 48, 12)):
    nx, ny, nz = dims
    dens, alb, ori = procedural_weave(nx, ny, nz, seed=3)
    vs = 1.0 / nx
    bbox = ((0.0, 0.0, 0.0), (1.0, ny * vs, nz * vs))
    d = Path(tmp) / "fabric"
    write_fabric(d, dens, alb, ori, bbox, density_scale=round(1.5 / vs, 3), roughness=0.3)
    return d


def set_variant(mi, variant):
    import drjit as dr
    mi.set_variant(variant)
    define_fixed_sggx(mi, dr)


def cmd_agree(args):
    import mitsuba as mi
    set_variant(mi, args.variant)
    binary = fabric_binary(args.bin)
    tmp = Path(tempfile.mkdtemp(prefix="mitsuba_compare_"))
    fabric = Path(args.fabric) if args.fabric else small_fabric(tmp)
    inputs, bbox, mat, dims = prepare_mitsuba_inputs(fabric, tmp / "mitsuba")
    w, h = args.size
    results, ok = [], True
    print(f"fabric {fabric} {dims[0]}x{dims[1]}x{dims[2]}, {w}x{h}, {args.spp} spp x 2 seeds per renderer, Mitsuba {mi.__version__} {args.variant}")
    print(f"{'view':30s} {'mean ours':>11s} {'mean mitsuba':>12s} {'rel diff':>9s} {'noise(mean)':>11s} {'RMS/noise':>9s} {'relRMSE':>8s}  verdict")
    env = write_envmap(tmp / "env.exr")
    for view in AGREE_VIEWS:
        if args.only and args.only not in view["name"]:
            continue
        v = resolve_view(view, bbox)
        if v.get("envmap") == "ENV":
            v["envmap"] = env
        v["phase"] = "sggx" if args.phase == "native" else "sggx_fixed"
        a1, _ = render_fabric(binary, fabric, v, w, h, args.spp, 1, tmp / "a1.exr")
        a2, _ = render_fabric(binary, fabric, v, w, h, args.spp, 2, tmp / "a2.exr")
        sd = mitsuba_scene(mi, v, inputs, bbox, mat, w, h, args.spp)
        m1, _ = render_mitsuba(mi, sd, args.spp, 11)
        m2, _ = render_mitsuba(mi, sd, args.spp, 12)
        a, m = 0.5 * (a1 + a2), 0.5 * (m1 + m2)
        noise_a2 = np.mean((a1 - a2) ** 2) / 2   # variance of one render, per value
        noise_m2 = np.mean((m1 - m2) ** 2) / 2
        # Averages of two renders: variance halves.
        expected = np.sqrt((noise_a2 + noise_m2) / 2)
        rms = np.sqrt(np.mean((a - m) ** 2))
        ratio = rms / max(expected, 1e-30)
        mean_a, mean_m = a.mean(), m.mean()
        rel = mean_a / mean_m - 1
        # Standard error of the relative mean difference, from the per-pixel noise.
        se_rel = np.sqrt((noise_a2 + noise_m2) / 2 / a.size) / mean_m
        rel_rmse = np.sqrt(np.sum((a - m) ** 2) / np.sum(m ** 2))
        passed = abs(rel) < 0.01 and ratio < 1.15
        ok &= passed
        print(f"{view['name']:30s} {mean_a:11.6f} {mean_m:12.6f} {rel:+9.4f} {se_rel:11.4f} {ratio:9.3f} {rel_rmse:8.4f}  {'ok' if passed else 'FAIL'}")
        results.append({"view": view["name"], "mean_ours": mean_a, "mean_mitsuba": mean_m, "relative_mean_difference": rel, "stderr_relative_mean": se_rel,
                        "rms_over_noise": ratio, "relative_rmse": rel_rmse, "passed": bool(passed)})
    if args.json:
        Path(args.json).write_text(json.dumps({"fabric": str(fabric), "size": [w, h], "spp": args.spp, "variant": args.variant, "views": results}, indent=2))
    if not args.keep:
        shutil.rmtree(tmp, ignore_errors=True)
    print("all views agree" if ok else "SOME VIEWS DISAGREE")
    return 0 if ok else 1


BENCH_VIEWS = [
    {"name": "ortho-top", "view_angles": (0.0, 0.0), "light_angles": (35.0, -60.0)},
    {"name": "ortho-oblique", "view_angles": (60.0, 30.0), "light_angles": (40.0, 200.0)},
    {"name": "persp-point", "origin": (0.5, -0.7, 0.6), "target": (0.5, 0.5, 0.0), "up": (0, 0, 1), "fov": 45.0, "point_light": (0.9, -0.2, 0.8), "intensity": 1.0},
]


def cmd_bench(args):
    import mitsuba as mi
    binary = fabric_binary(args.bin)
    tmp = Path(tempfile.mkdtemp(prefix="mitsuba_bench_"))
    if args.fabric:
        fabric = Path(args.fabric)
    else:
        fabric = small_fabric(tmp, (256, 256, 48))
    inputs, bbox, mat, dims = prepare_mitsuba_inputs(fabric, tmp / "mitsuba")
    w, h = args.size
    ncpu = os.cpu_count()
    print(f"fabric {fabric} {dims[0]}x{dims[1]}x{dims[2]} (density scale {mat['density_scale']}, roughness {mat['roughness']}), {w}x{h} at {args.spp} spp, {ncpu} CPUs")
    rows = []
    for view in BENCH_VIEWS:
        v = resolve_view(view, bbox)
        ours, rep = render_fabric(binary, fabric, v, w, h, args.spp, 1, tmp / "ours.exr")
        row = {"view": view["name"], "fabric_paths_per_s": rep["paths_per_second"], "fabric_mean": float(ours.mean()), "scatterings_per_path": rep["scatterings_per_path"]}
        for variant in args.variants:
            set_variant(mi, variant)
            v["phase"] = "sggx" if args.phase == "native" else "sggx_fixed"
            sd = mitsuba_scene(mi, v, inputs, bbox, mat, w, h, args.spp)
            if variant.startswith("llvm"):
                render_mitsuba(mi, mitsuba_scene(mi, v, inputs, bbox, mat, 8, 8, 1), 1, 0)  # JIT warm-up
            img, secs = render_mitsuba(mi, sd, args.spp, 5)
            row[f"{variant}_paths_per_s"] = w * h * args.spp / secs
            row[f"{variant}_mean"] = float(img.mean())
        rows.append(row)
        line = f"{view['name']:14s} fabric {row['fabric_paths_per_s']:12.0f} paths/s ({row['scatterings_per_path']:.2f} scatterings/path)"
        for variant in args.variants:
            pps = row[f"{variant}_paths_per_s"]
            line += f" | {variant} {pps:11.0f} paths/s, ratio {row['fabric_paths_per_s'] / pps:6.2f}x, means {row['fabric_mean']:.5f}/{row[f'{variant}_mean']:.5f}"
        print(line, flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({"fabric": str(fabric), "dims": list(dims), "size": [w, h], "spp": args.spp, "cpus": ncpu, "views": rows}, indent=2))
    if not args.keep:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


def parse_size(s):
    w, h = s.lower().split("x")
    return int(w), int(h)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("agree", help="image agreement on a small fabric, several views")
    a.add_argument("--fabric", help="fabric directory (default: a procedural 48x48x12 weave)")
    a.add_argument("--spp", type=int, default=256)
    a.add_argument("--size", type=parse_size, default=(48, 48))
    a.add_argument("--variant", default="llvm_ad_rgb")
    a.add_argument("--only", help="run only the views whose name contains this")
    b = sub.add_parser("bench", help="paths per second on the 256x256x48 twill")
    b.add_argument("--fabric", help="fabric directory (default: a procedural 256x256x48 twill)")
    b.add_argument("--spp", type=int, default=16)
    b.add_argument("--size", type=parse_size, default=(128, 128))
    b.add_argument("--variants", type=lambda s: s.split(","), default=["scalar_rgb", "llvm_ad_rgb"])
    for q in (a, b):
        q.add_argument("--phase", choices=["fixed", "native"], default="fixed", help="SGGX sampling of Mitsuba: corrected (default) or its own")
        q.add_argument("--bin", help="fabric binary (default: $CARGO_TARGET_DIR/release/fabric)")
        q.add_argument("--json", help="write the results as JSON here")
        q.add_argument("--keep", action="store_true", help="keep the temporary directory")
    args = p.parse_args()
    sys.exit(cmd_agree(args) if args.cmd == "agree" else cmd_bench(args))


if __name__ == "__main__":
    main()
