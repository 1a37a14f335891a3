//! Scene description shared by every renderer: cameras, lights, environment maps, rays, base meshes.

pub mod aabb;
pub mod camera;
pub mod env_lights;
pub mod env_prefilter;
pub mod envmap;
pub mod light;
pub mod mesh;
pub mod ray;
pub mod sky;

pub use aabb::Aabb;
pub use camera::{Camera, CameraError, CameraFrame, Projection, direction_from_angles};
pub use env_lights::{ExtractOptions, extract_lights};
pub use env_prefilter::PrefilteredEnv;
pub use envmap::{EnvMap, EnvMapError, EnvMapOptions, EnvSample};
pub use mesh::{Mesh, MeshError, Vertex};
pub use light::{Light, LightError, LightSample};
pub use ray::Ray;
pub use sky::Sky;
