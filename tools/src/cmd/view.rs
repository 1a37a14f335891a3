//! `fabric view`: the GPU renderer in a window (winit), with an orbit camera and live
//! edits. Without a model it draws the base mesh scene; with `MODEL.hyb` it draws the
//! hybrid fabric tiled over the mesh (`--mesh`, default plane; `--uv-scale`) and lets
//! the appearance be edited live, without re-baking, with the same edits as the flags
//! of `fabric render`. `--frames N` closes after N frames (tests, scripted
//! screenshots); `--screenshot PATH` saves the last frame's linear image. The frame
//! loop itself (swapchain, offscreen target, tonemap) is `fabric_runtime::gpu::FrameLoop`.
//!
//! Controls: left-drag orbits the camera, wheel zooms, right-drag moves the light,
//! `+`/`-` exposure, Esc or closing the window quits. With a model: `r`/`R` roughness
//! ×1.25/÷1.25, `[`/`]` tangent rotation ∓15°, `t` cycles the tint, `f` flyaways
//! on/off, `b`/`v` level bias ±0.5, `m` the edit mask on/off, `0` resets the edits. The
//! window title shows the GPU frame time and the edits.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context, Result, anyhow};
use clap::Args;
use fabric_runtime::cpu::{CpuRenderOptions, LevelChoice};
use fabric_runtime::gpu::{FrameLoop, HybridPass, MeshPass, ViewContent};
use fabric_runtime::hybrid::format::read_file;
use fabric_runtime::scene::{Camera, Light, Mesh};
use fabric_runtime::vk::swapchain::{required_device_extensions, required_instance_extensions};
use fabric_runtime::vk::{Device, DeviceOptions, InstanceOptions, Surface};
use glam::Vec3;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::raw_window_handle::{HasDisplayHandle, HasWindowHandle};
use winit::window::{Window, WindowId};

use super::render_cpu::CpuRenderFlags;
use crate::args::{CameraArgs, EnvArgs, LightArgs, MeshSceneArgs};

#[derive(Args, Debug)]
pub struct ViewArgs {
    /// A hybrid model (.hyb) to draw on the mesh; without it the base mesh scene.
    pub model: Option<PathBuf>,
    #[command(flatten)]
    pub scene: MeshSceneArgs,
    /// Exposure of the sRGB display mapping.
    #[arg(long, default_value_t = 1.0)]
    pub exposure: f32,
    /// Close after this many frames.
    #[arg(long)]
    pub frames: Option<u32>,
    /// Save the last frame (linear radiance: .exr, or .png with the exposure) on exit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    #[command(flatten)]
    pub camera: CameraArgs,
    #[command(flatten)]
    pub light: LightArgs,
    /// With a model: `--envmap FILE|sky` lights it with an environment map (its sources
    /// as lights, the rest through the lobes' SG mixtures).
    #[command(flatten)]
    pub env: EnvArgs,
    #[command(flatten)]
    pub render: CpuRenderFlags,
}

/// Spherical coordinates of the camera around its target.
#[derive(Clone, Copy, Debug)]
struct Orbit {
    target: Vec3,
    distance: f32,
    theta: f32,
    phi: f32,
}

impl Orbit {
    fn from_camera(c: &Camera) -> Orbit {
        let v = c.origin - c.target;
        let distance = v.length().max(1e-3);
        Orbit { target: c.target, distance, theta: (v.z / distance).clamp(-1.0, 1.0).acos(), phi: v.y.atan2(v.x) }
    }

    fn apply(&self, c: &mut Camera) {
        let (st, ct) = self.theta.sin_cos();
        let (sp, cp) = self.phi.sin_cos();
        c.origin = self.target + self.distance * Vec3::new(st * cp, st * sp, ct);
        c.target = self.target;
        c.up = Vec3::Z;
    }
}

/// Tints `t` cycles through.
const TINTS: [Vec3; 4] = [Vec3::ONE, Vec3::new(1.0, 0.55, 0.55), Vec3::new(0.55, 0.75, 1.0), Vec3::new(1.0, 0.85, 0.45)];

/// The window and its frame loop. The frame loop drops first (it owns the surface
/// made for the window).
struct Viewer {
    frame_loop: FrameLoop,
    window: Window,
    camera: Camera,
    orbit: Orbit,
    /// The delta light right-drag moves (none with an environment map and no light flag).
    light: Option<Light>,
    exposure: f32,
    /// Hybrid content: the options and edits drawn with, the tint index, the mask.
    options: CpuRenderOptions,
    tint: usize,
    mask: Option<Arc<fabric_runtime::cpu::EditMask>>,
    hybrid: bool,
}

impl Viewer {
    fn new(event_loop: &ActiveEventLoop, args: &ViewArgs, mesh: &Mesh) -> Result<Viewer> {
        let (w, h) = args.camera.size;
        let window = event_loop
            .create_window(Window::default_attributes().with_title("fabric view").with_inner_size(PhysicalSize::new(w, h)))
            .context("cannot open a window (is DISPLAY set? for headless use: Xvfb :99 & DISPLAY=:99)")?;
        let display = event_loop.display_handle().context("window system display handle")?.as_raw();
        let device = Device::new(&DeviceOptions {
            name: args.scene.device.clone(),
            instance: InstanceOptions { extensions: required_instance_extensions(display)?, ..Default::default() },
            extensions: required_device_extensions(),
        })
        .context("cannot open a Vulkan device")?;
        let surface = Arc::new(Surface::new(device.instance(), display, window.window_handle().context("window handle")?.as_raw())?);
        let mut options = args.render.options()?;
        options.periodic = true;
        if args.env.envmap.is_some() && args.model.is_none() {
            anyhow::bail!("--envmap lights a hybrid model: give MODEL.hyb");
        }
        // With a map, the delta light only when a light flag asks for it.
        let lights = super::render_cpu::lights_and_env(&args.light, &args.env, &mut options)?;
        let content = match &args.model {
            Some(path) => {
                let model = read_file(path)?;
                let pass = HybridPass::new(&device)?;
                let gpu_model = pass.upload(&model, true).with_context(|| format!("cannot upload {}", path.display()))?;
                let gpu_mesh = pass.upload_mesh(mesh)?;
                ViewContent::Hybrid { pass, model: gpu_model, mesh: gpu_mesh, uv_scale: args.scene.uv_scale, draw: None }
            }
            None => {
                let pass = MeshPass::new(&device)?;
                let gpu_mesh = pass.upload(mesh)?;
                let frame = pass.frame_resources()?;
                ViewContent::Mesh { pass, mesh: gpu_mesh, frame, base_color: args.scene.base_color }
            }
        };
        let size = window.inner_size();
        let frame_loop = FrameLoop::new(&device, surface, size.width, size.height, content)?;
        let mut camera = args.camera.camera(mesh.bounds())?;
        (camera.width, camera.height) = frame_loop.extent();
        let orbit = Orbit::from_camera(&camera);
        println!("device: {} ({}); window {}x{}, swapchain {:?}", device.info().name, device.info().kind, camera.width, camera.height, frame_loop.swapchain_format());
        let mask = options.edits.mask.clone();
        Ok(Viewer { frame_loop, window, camera, orbit, light: lights.first().copied(), exposure: args.exposure, options, tint: 0, mask, hybrid: args.model.is_some() })
    }

    fn draw(&mut self) -> Result<()> {
        self.orbit.apply(&mut self.camera);
        let size = self.window.inner_size();
        self.frame_loop.draw((size.width, size.height), &mut self.camera, self.light.as_slice(), &self.options, self.exposure)?;
        let f = &self.frame_loop;
        let edits = if self.hybrid {
            let e = &self.options.edits;
            let bias = match self.options.level {
                LevelChoice::Auto { bias } | LevelChoice::Nearest { bias } => bias,
                LevelChoice::Fixed(_) => 0.0,
            };
            format!(
                " — roughness ×{:.2}, rotation {:.0}°, tint {:.2},{:.2},{:.2}{}, flyaways {}, level bias {:+.1}",
                e.roughness_scale,
                e.tangent_rotation.to_degrees(),
                e.tint.x,
                e.tint.y,
                e.tint.z,
                if e.mask.is_some() { " (masked)" } else { "" },
                if self.options.flyaways { "on" } else { "off" },
                bias
            ) + &self.options.env.as_ref().map(|e| format!(", environment turned {:.0}°", e.prefiltered.map.rotate_deg())).unwrap_or_default()
        } else {
            String::new()
        };
        self.window.set_title(&format!("fabric view — GPU {:.2} ms — exposure {:.2}{edits} — {}", f.gpu_ms, self.exposure, f.device().info().name));
        Ok(())
    }

    /// A key that edits the hybrid model; true if it was one.
    fn edit(&mut self, key: &str) -> bool {
        if !self.hybrid {
            return false;
        }
        let e = &mut self.options.edits;
        match key {
            "r" => e.roughness_scale = (e.roughness_scale * 1.25).min(64.0),
            "R" => e.roughness_scale = (e.roughness_scale / 1.25).max(1.0 / 64.0),
            "[" => e.tangent_rotation -= 15f32.to_radians(),
            "]" => e.tangent_rotation += 15f32.to_radians(),
            "t" => {
                self.tint = (self.tint + 1) % TINTS.len();
                e.tint = TINTS[self.tint];
            }
            "m" => e.mask = if e.mask.is_some() { None } else { self.mask.clone() },
            "0" => {
                *e = fabric_runtime::cpu::Edits { mask: self.mask.clone(), ..Default::default() };
                self.tint = 0;
            }
            "f" => self.options.flyaways = !self.options.flyaways,
            // Turn the environment (and the sources taken out of it) about +Z, live.
            "e" | "E" => {
                let Some(env) = self.options.env.as_mut() else { return false };
                let step = if key == "e" { 15.0 } else { -15.0 };
                match env.prefiltered.rotated(env.prefiltered.map.rotate_deg() + step) {
                    Ok(p) => env.prefiltered = Arc::new(p),
                    Err(e) => eprintln!("cannot turn the environment: {e}"),
                }
            }
            "b" | "v" => {
                let step = if key == "b" { 0.5 } else { -0.5 };
                self.options.level = match self.options.level {
                    LevelChoice::Auto { bias } => LevelChoice::Auto { bias: bias + step },
                    LevelChoice::Nearest { bias } => LevelChoice::Nearest { bias: bias + step },
                    fixed => fixed,
                };
            }
            _ => return false,
        }
        true
    }
}

struct App {
    args: ViewArgs,
    mesh: Mesh,
    viewer: Option<Viewer>,
    error: Option<anyhow::Error>,
    dragging: Option<MouseButton>,
    cursor: Option<(f64, f64)>,
}

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: anyhow::Error) {
        self.error.get_or_insert(e);
        event_loop.exit();
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.viewer.is_none() {
            match Viewer::new(event_loop, &self.args, &self.mesh) {
                Ok(v) => self.viewer = Some(v),
                Err(e) => self.fail(event_loop, e),
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(v) = self.viewer.as_mut() else { return };
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(_) => v.frame_loop.mark_resized(),
            WindowEvent::RedrawRequested => {
                if let Err(e) = v.draw() {
                    return self.fail(event_loop, e);
                }
                if self.args.frames.is_some_and(|n| v.frame_loop.frames >= n) {
                    event_loop.exit();
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                self.dragging = (state == ElementState::Pressed).then_some(button);
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let (Some(button), Some((x0, y0))) = (self.dragging, self.cursor) {
                    let (dx, dy) = ((position.x - x0) as f32 * 0.01, (position.y - y0) as f32 * 0.01);
                    match button {
                        MouseButton::Left => {
                            v.orbit.phi -= dx;
                            v.orbit.theta = (v.orbit.theta - dy).clamp(0.01, std::f32::consts::PI - 0.01);
                        }
                        MouseButton::Right => {
                            if let Some(Light::Directional { dir_to_light, .. }) = &mut v.light {
                                let rot = glam::Quat::from_rotation_z(-dx) * glam::Quat::from_axis_angle(Vec3::Z.cross(*dir_to_light).normalize_or(Vec3::X), -dy);
                                *dir_to_light = (rot * *dir_to_light).normalize();
                            }
                        }
                        _ => {}
                    }
                }
                self.cursor = Some((position.x, position.y));
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let s = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                v.orbit.distance *= 0.9f32.powf(s);
            }
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => match event.logical_key {
                Key::Named(NamedKey::Escape) => event_loop.exit(),
                Key::Character(c) if c == "+" || c == "=" => v.exposure *= 1.25,
                Key::Character(c) if c == "-" => v.exposure /= 1.25,
                Key::Character(c) => {
                    v.edit(c.as_str());
                }
                _ => {}
            },
            _ => {}
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(v) = &self.viewer {
            v.window.request_redraw();
        }
    }
}

pub fn run(args: ViewArgs) -> Result<()> {
    let default_mesh = if args.model.is_some() { "plane" } else { "sphere" };
    let mesh = Mesh::by_name(args.scene.mesh.as_deref().unwrap_or(default_mesh))?;
    let event_loop = EventLoop::new().map_err(|e| anyhow!("cannot connect to the window system ({e}); is DISPLAY set? for headless use: Xvfb :99 & DISPLAY=:99"))?;
    let mut app = App { args, mesh, viewer: None, error: None, dragging: None, cursor: None };
    event_loop.run_app(&mut app).context("window event loop")?;
    if let Some(e) = app.error.take() {
        return Err(e);
    }
    let viewer = app.viewer.take().context("the window never opened")?;
    if let Some(path) = &app.args.screenshot {
        viewer.frame_loop.screenshot()?.write(path, viewer.exposure)?;
        println!("wrote {}", path.display());
    }
    let f = &viewer.frame_loop;
    println!("{} frames, last GPU frame time {:.3} ms on {}", f.frames, f.gpu_ms, f.device().info().name);
    if let Some(v) = f.variant {
        println!("variant: flyaways {}, shadows {}, {} light(s){}{}", if v.flyaways { "marched" } else { "skipped" }, if v.shadows { "on" } else { "off" }, v.lights, if v.env { ", environment map" } else { "" }, if v.transmission { ", transmission (light from behind the cloth: a light, or the map below the sheet)" } else { "" });
    }
    let device = f.device().clone();
    drop(viewer); // destruction can report validation errors too
    let errors = device.validation_errors();
    if !errors.is_empty() {
        anyhow::bail!("{} Vulkan validation error(s); first: {}", errors.len(), errors[0]);
    }
    Ok(())
}
