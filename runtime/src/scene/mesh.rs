//! Base meshes: triangle lists with positions, normals, tangents (xyz + handedness w)
//! and UVs. Built-in shapes (plane, UV sphere, cylinder) and OBJ files (via `tobj`;
//! tangents derived from the UVs when the file has none).
//!
//! Conventions: the plane lies in z = 0 facing +Z with u along +X and v along +Y, so a
//! fabric tile drawn on it has its x, y axes where the volume had them. Tangents point
//! along increasing u; bitangent = w · (n × t) points along increasing v.

use std::path::Path;

use glam::{Vec2, Vec3, Vec4};

/// One vertex as the GPU reads it (48 bytes, std430-compatible).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub tangent: [f32; 4],
    pub uv: [f32; 2],
}

const _: () = assert!(core::mem::size_of::<Vertex>() == 48);

/// The largest vertex coordinate accepted from a file: beyond it the bounds, the camera
/// framing and f32 positions lose meaning (a diagonal of 1e20 overflows its square).
pub const MAX_COORDINATE: f32 = 1e9;

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub vertices: Vec<Vertex>,
    pub indices: Vec<u32>,
}

#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("{path}: cannot read OBJ: {source}")]
    Obj { path: String, source: tobj::LoadError },
    #[error("{path}: the OBJ file has no triangles")]
    Empty { path: String },
    #[error("{path}: vertex {index} has a non-finite position")]
    NonFinite { path: String, index: usize },
    #[error("{path}: vertex {index} has a non-finite {what}")]
    NonFiniteAttribute { path: String, index: usize, what: &'static str },
    #[error("{path}: vertex {index} lies {distance:e} units from the origin (at most {MAX_COORDINATE:e}: move or scale the mesh)")]
    TooFar { path: String, index: usize, distance: f32 },
    #[error("{path}: all {triangles} triangles have zero area (no surface to draw)")]
    Degenerate { path: String, triangles: usize },
    #[error("unknown mesh '{0}' (use plane, sphere, cylinder or a path to an .obj file)")]
    Unknown(String),
    #[error("mesh parameter {what} = {value} is out of range")]
    BadParameter { what: &'static str, value: f32 },
}

impl Mesh {
    /// A `width` × `height` rectangle centred at the origin in z = 0, facing +Z.
    pub fn plane(width: f32, height: f32) -> Mesh {
        let (hw, hh) = (0.5 * width, 0.5 * height);
        let v = |x: f32, y: f32, u: f32, w: f32| Vertex { position: [x, y, 0.0], normal: [0.0, 0.0, 1.0], tangent: [1.0, 0.0, 0.0, 1.0], uv: [u, w] };
        Mesh { vertices: vec![v(-hw, -hh, 0.0, 0.0), v(hw, -hh, 1.0, 0.0), v(hw, hh, 1.0, 1.0), v(-hw, hh, 0.0, 1.0)], indices: vec![0, 1, 2, 0, 2, 3] }
    }

    /// A UV sphere of `radius` at the origin; u wraps around +Z (from +X), v from the
    /// south pole (0) to the north pole (1).
    pub fn sphere(radius: f32, segments: u32, rings: u32) -> Mesh {
        let (segments, rings) = (segments.max(3), rings.max(2));
        let mut m = Mesh::default();
        for r in 0..=rings {
            let v = r as f32 / rings as f32;
            let theta = std::f32::consts::PI * (1.0 - v); // from +Z down
            for s in 0..=segments {
                let u = s as f32 / segments as f32;
                let phi = 2.0 * std::f32::consts::PI * u;
                let n = Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
                let t = Vec3::new(-phi.sin(), phi.cos(), 0.0);
                m.vertices.push(Vertex { position: (n * radius).to_array(), normal: n.to_array(), tangent: [t.x, t.y, t.z, 1.0], uv: [u, v] });
            }
        }
        m.grid_indices(segments, rings);
        m
    }

    /// An open cylinder of `radius` and `height` around the z axis, centred at the origin.
    pub fn cylinder(radius: f32, height: f32, segments: u32) -> Mesh {
        let segments = segments.max(3);
        let mut m = Mesh::default();
        for r in 0..=1 {
            let v = r as f32;
            for s in 0..=segments {
                let u = s as f32 / segments as f32;
                let phi = 2.0 * std::f32::consts::PI * u;
                let n = Vec3::new(phi.cos(), phi.sin(), 0.0);
                let t = Vec3::new(-phi.sin(), phi.cos(), 0.0);
                let p = n * radius + Vec3::Z * (v - 0.5) * height;
                m.vertices.push(Vertex { position: p.to_array(), normal: n.to_array(), tangent: [t.x, t.y, t.z, 1.0], uv: [u, v] });
            }
        }
        m.grid_indices(segments, 1);
        m
    }

    fn grid_indices(&mut self, segments: u32, rings: u32) {
        let row = segments + 1;
        for r in 0..rings {
            for s in 0..segments {
                let (a, b, c, d) = (r * row + s, r * row + s + 1, (r + 1) * row + s + 1, (r + 1) * row + s);
                self.indices.extend_from_slice(&[a, b, c, a, c, d]);
            }
        }
    }

    /// Loads an OBJ file (triangulated; normals and UVs used when present).
    pub fn load_obj(path: &Path) -> Result<Mesh, MeshError> {
        let p = path.display().to_string();
        let (models, _) = tobj::load_obj(path, &tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true }).map_err(|source| MeshError::Obj { path: p.clone(), source })?;
        let mut m = Mesh::default();
        for model in models {
            let mesh = model.mesh;
            let base = m.vertices.len() as u32;
            let n = mesh.positions.len() / 3;
            for i in 0..n {
                let pos = [mesh.positions[3 * i], mesh.positions[3 * i + 1], mesh.positions[3 * i + 2]];
                let index = m.vertices.len();
                if !pos.iter().all(|c| c.is_finite()) {
                    return Err(MeshError::NonFinite { path: p, index });
                }
                let distance = Vec3::from(pos).abs().max_element();
                if distance > MAX_COORDINATE {
                    return Err(MeshError::TooFar { path: p, index, distance });
                }
                let normal = if mesh.normals.len() >= 3 * (i + 1) { [mesh.normals[3 * i], mesh.normals[3 * i + 1], mesh.normals[3 * i + 2]] } else { [0.0; 3] };
                let uv = if mesh.texcoords.len() >= 2 * (i + 1) { [mesh.texcoords[2 * i], mesh.texcoords[2 * i + 1]] } else { [0.0; 2] };
                // A NaN UV would tile NaN texel coordinates; a NaN normal is derived again
                // below like a missing one, but a file that stores it is corrupt.
                if !uv.iter().all(|c| c.is_finite()) {
                    return Err(MeshError::NonFiniteAttribute { path: p, index, what: "texture coordinate (vt)" });
                }
                if !normal.iter().all(|c| c.is_finite()) {
                    return Err(MeshError::NonFiniteAttribute { path: p, index, what: "normal (vn)" });
                }
                m.vertices.push(Vertex { position: pos, normal, tangent: [0.0; 4], uv });
            }
            for &idx in &mesh.indices {
                if idx as usize >= n {
                    return Err(MeshError::Obj { path: p, source: tobj::LoadError::FaceVertexOutOfBounds });
                }
                m.indices.push(base + idx);
            }
        }
        if m.indices.len() < 3 {
            return Err(MeshError::Empty { path: p });
        }
        if m.triangle_areas().all(|a| a <= 0.0) {
            return Err(MeshError::Degenerate { path: p, triangles: m.indices.len() / 3 });
        }
        m.derive_missing_frames();
        Ok(m)
    }

    /// Fills zero normals with area-weighted face normals and derives tangents from the
    /// UV parametrization (per-triangle dP/du accumulated, Gram–Schmidt against n,
    /// handedness from dP/dv), falling back to any vector ⟂ n where UVs are degenerate.
    pub fn derive_missing_frames(&mut self) {
        let nv = self.vertices.len();
        let mut face_n = vec![Vec3::ZERO; nv];
        let mut tan = vec![Vec3::ZERO; nv];
        let mut bit = vec![Vec3::ZERO; nv];
        for tri in self.indices.chunks_exact(3) {
            let [a, b, c] = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
            let (p0, p1, p2) = (Vec3::from(self.vertices[a].position), Vec3::from(self.vertices[b].position), Vec3::from(self.vertices[c].position));
            let (w0, w1, w2) = (Vec2::from(self.vertices[a].uv), Vec2::from(self.vertices[b].uv), Vec2::from(self.vertices[c].uv));
            let (e1, e2) = (p1 - p0, p2 - p0);
            let (d1, d2) = (w1 - w0, w2 - w0);
            let fnrm = e1.cross(e2);
            let det = d1.x * d2.y - d2.x * d1.y;
            let (t, bt) = if det.abs() > 1e-12 { ((e1 * d2.y - e2 * d1.y) / det, (e2 * d1.x - e1 * d2.x) / det) } else { (Vec3::ZERO, Vec3::ZERO) };
            for i in [a, b, c] {
                face_n[i] += fnrm;
                tan[i] += t;
                bit[i] += bt;
            }
        }
        for (i, v) in self.vertices.iter_mut().enumerate() {
            let mut n = Vec3::from(v.normal);
            if n.length_squared() < 1e-12 || !n.is_finite() {
                n = face_n[i];
            }
            let n = n.try_normalize().unwrap_or(Vec3::Z);
            v.normal = n.to_array();
            let given = Vec4::from(v.tangent);
            if given.truncate().length_squared() > 1e-12 && given.is_finite() {
                continue;
            }
            let t = (tan[i] - n * n.dot(tan[i])).try_normalize().unwrap_or_else(|| n.any_orthonormal_vector());
            let w = if n.cross(t).dot(bit[i]) < 0.0 { -1.0 } else { 1.0 };
            v.tangent = [t.x, t.y, t.z, w];
        }
    }

    /// A built-in mesh by name, or an OBJ file by path.
    pub fn by_name(name: &str) -> Result<Mesh, MeshError> {
        match name {
            "plane" => Ok(Mesh::plane(2.0, 2.0)),
            "sphere" => Ok(Mesh::sphere(1.0, 96, 48)),
            "cylinder" => Ok(Mesh::cylinder(1.0, 2.0, 96)),
            p if p.to_ascii_lowercase().ends_with(".obj") => Mesh::load_obj(Path::new(p)),
            other => Err(MeshError::Unknown(other.into())),
        }
    }

    /// Each triangle's area (0 for a degenerate one).
    pub fn triangle_areas(&self) -> impl Iterator<Item = f32> + '_ {
        self.indices.chunks_exact(3).map(|t| {
            let p = |i: u32| Vec3::from(self.vertices[i as usize].position);
            0.5 * (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).length()
        })
    }

    /// Axis-aligned bounds of the vertices.
    pub fn bounds(&self) -> super::Aabb {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for v in &self.vertices {
            lo = lo.min(Vec3::from(v.position));
            hi = hi.max(Vec3::from(v.position));
        }
        super::Aabb::new(lo, hi)
    }

    /// Moves and scales every vertex: p' = p · scale + offset.
    pub fn transform(mut self, scale: f32, offset: Vec3) -> Mesh {
        for v in &mut self.vertices {
            v.position = (Vec3::from(v.position) * scale + offset).to_array();
        }
        self
    }

    /// Appends another mesh.
    pub fn append(&mut self, other: &Mesh) {
        let base = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&other.vertices);
        self.indices.extend(other.indices.iter().map(|i| i + base));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_frames(m: &Mesh) {
        for v in &m.vertices {
            let n = Vec3::from(v.normal);
            let t = Vec4::from(v.tangent);
            assert!((n.length() - 1.0).abs() < 1e-4, "{v:?}");
            assert!((t.truncate().length() - 1.0).abs() < 1e-4 && n.dot(t.truncate()).abs() < 1e-4 && t.w.abs() == 1.0, "{v:?}");
        }
        for tri in m.indices.chunks_exact(3) {
            assert!(tri.iter().all(|&i| (i as usize) < m.vertices.len()));
        }
    }

    #[test]
    fn builtin_meshes_have_orthonormal_frames_and_outward_winding() {
        for m in [Mesh::plane(2.0, 1.0), Mesh::sphere(1.0, 16, 8), Mesh::cylinder(1.0, 2.0, 16)] {
            check_frames(&m);
            // Counter-clockwise seen from outside: the face normal agrees with vertex normals.
            for tri in m.indices.chunks_exact(3) {
                let p: Vec<Vec3> = tri.iter().map(|&i| Vec3::from(m.vertices[i as usize].position)).collect();
                let fnrm = (p[1] - p[0]).cross(p[2] - p[0]);
                if fnrm.length() < 1e-6 {
                    continue; // pole triangles of the sphere are degenerate
                }
                let vn: Vec3 = tri.iter().map(|&i| Vec3::from(m.vertices[i as usize].normal)).sum();
                assert!(fnrm.dot(vn) > 0.0);
            }
        }
    }

    #[test]
    fn obj_without_normals_or_tangents_gets_them() {
        let dir = std::env::temp_dir().join(format!("fabric-mesh-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("quad.obj");
        std::fs::write(&p, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n").unwrap();
        let m = Mesh::load_obj(&p).unwrap();
        assert_eq!(m.indices.len(), 6);
        check_frames(&m);
        assert!(Vec3::from(m.vertices[0].normal).abs_diff_eq(Vec3::Z, 1e-5));
        assert!(Vec4::from(m.vertices[0].tangent).abs_diff_eq(Vec4::new(1.0, 0.0, 0.0, 1.0), 1e-5));
        std::fs::write(&p, "v 0 0 0\nv 1 0 0\nf 1 2 7\n").unwrap();
        assert!(Mesh::load_obj(&p).is_err());
        std::fs::write(&p, "garbage\n").unwrap();
        assert!(matches!(Mesh::load_obj(&p), Err(MeshError::Empty { .. })));
        assert!(Mesh::load_obj(&dir.join("missing.obj")).is_err());
        // Corrupt files found by an audit: each gets its own message, none a black image.
        let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n";
        std::fs::write(&p, format!("{tri}f 1/1 2/2\nl 1 2\nf 3\n")).unwrap();
        assert!(matches!(Mesh::load_obj(&p), Err(MeshError::Empty { .. })), "lines and points are not triangles");
        std::fs::write(&p, "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt nan 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n").unwrap();
        let e = Mesh::load_obj(&p).unwrap_err();
        assert!(matches!(e, MeshError::NonFiniteAttribute { index: 0, .. }) && e.to_string().contains("texture coordinate"), "{e}");
        std::fs::write(&p, format!("{tri}vn 0 0 inf\nf 1/1/1 2/2/1 3/3/1\n")).unwrap();
        assert!(matches!(Mesh::load_obj(&p), Err(MeshError::NonFiniteAttribute { what: "normal (vn)", .. })));
        std::fs::write(&p, "v 1e30 0 0\nv -1e30 0 0\nv 0 1e30 0\nf 1 2 3\n").unwrap();
        let e = Mesh::load_obj(&p).unwrap_err();
        assert!(matches!(e, MeshError::TooFar { index: 0, .. }) && e.to_string().contains("1e30"), "{e}");
        std::fs::write(&p, "v 0 0 0\nv 0 0 0\nv 1 1 1\nv 2 2 2\nf 1 2 3\nf 1 3 4\n").unwrap();
        let e = Mesh::load_obj(&p).unwrap_err();
        assert!(matches!(e, MeshError::Degenerate { triangles: 2, .. }), "{e}");
        // One good triangle among degenerate ones is a mesh.
        std::fs::write(&p, "v 0 0 0\nv 0 0 0\nv 1 1 1\nv 1 0 0\nf 1 2 3\nf 1 3 4\n").unwrap();
        assert_eq!(Mesh::load_obj(&p).unwrap().triangle_areas().filter(|&a| a > 0.0).count(), 1);
        std::fs::remove_dir_all(&dir).ok();
    }
}
