//! `fabric view`: the GPU renderer in a window (winit), with an orbit camera and live
//! edits of the light and exposure. `--frames N` closes after N frames (for tests and
//! scripted screenshots); `--screenshot PATH` saves the last frame's linear image.
//!
//! Controls: left-drag orbits the camera, wheel zooms, right-drag moves the light,
//! `+`/`-` change the exposure, Esc or closing the window quits.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context, Result, anyhow};
use clap::Args;
use fabric_runtime::gpu::tonemap::DisplayImage;
use fabric_runtime::gpu::{GpuMesh, MeshFrame, MeshPass, OffscreenTarget, TonemapPass};
use fabric_runtime::scene::{Camera, Light, Mesh};
use fabric_runtime::vk::swapchain::{required_device_extensions, required_instance_extensions};
use fabric_runtime::vk::{Acquired, Device, DeviceOptions, InstanceOptions, Surface, Swapchain, Timestamps, vk};
use glam::Vec3;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::raw_window_handle::{HasDisplayHandle, HasWindowHandle};
use winit::window::{Window, WindowId};

use crate::args::{CameraArgs, LightArgs, MeshSceneArgs};

#[derive(Args, Debug)]
pub struct ViewArgs {
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

/// Everything that lives while the window is open. Fields drop in order: GPU
/// resources, then the swapchain, the surface, the device and last the window the
/// surface was made for.
struct Viewer {
    tonemap: TonemapPass,
    target: OffscreenTarget,
    frame: MeshFrame,
    gpu_mesh: GpuMesh,
    pass: MeshPass,
    timestamps: Timestamps,
    swapchain: Swapchain,
    surface: Arc<Surface>,
    device: Arc<Device>,
    window: Window,
    camera: Camera,
    orbit: Orbit,
    light: Light,
    exposure: f32,
    base_color: Vec3,
    frames: u32,
    gpu_ms: f64,
    resized: bool,
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
        let size = window.inner_size();
        let swapchain = Swapchain::new(&device, &surface, size.width.max(1), size.height.max(1))?;
        let mut camera = args.camera.camera(mesh.bounds())?;
        camera.width = swapchain.extent.width;
        camera.height = swapchain.extent.height;
        let orbit = Orbit::from_camera(&camera);
        let pass = MeshPass::new(&device)?;
        let gpu_mesh = pass.upload(mesh)?;
        let frame = pass.frame_resources()?;
        let target = OffscreenTarget::new(&device, camera.width, camera.height)?;
        let tonemap = TonemapPass::new(&device, &target, swapchain.format, swapchain.is_srgb())?;
        let timestamps = Timestamps::new(&device, 2)?;
        println!("device: {} ({}); window {}x{}, swapchain {:?}", device.info().name, device.info().kind, camera.width, camera.height, swapchain.format);
        Ok(Viewer {
            tonemap,
            target,
            frame,
            gpu_mesh,
            pass,
            timestamps,
            swapchain,
            surface,
            device,
            window,
            camera,
            orbit,
            light: args.light.light()?,
            exposure: args.exposure,
            base_color: args.scene.base_color,
            frames: 0,
            gpu_ms: 0.0,
            resized: false,
        })
    }

    /// Rebuilds the size-dependent objects for the window's current size.
    fn recreate(&mut self) -> Result<()> {
        let size = self.window.inner_size();
        if size.width == 0 || size.height == 0 {
            return Ok(()); // minimized: keep the old swapchain until we have a size
        }
        self.device.wait_idle()?;
        // Drop the old swapchain before making the new one for the same surface.
        let placeholder_target = OffscreenTarget::new(&self.device, 1, 1)?;
        self.tonemap = TonemapPass::new(&self.device, &placeholder_target, self.swapchain.format, self.swapchain.is_srgb())?;
        self.target = placeholder_target;
        self.swapchain = Swapchain::new(&self.device, &self.surface, size.width, size.height)?;
        self.camera.width = self.swapchain.extent.width;
        self.camera.height = self.swapchain.extent.height;
        self.target = OffscreenTarget::new(&self.device, self.camera.width, self.camera.height)?;
        self.tonemap = TonemapPass::new(&self.device, &self.target, self.swapchain.format, self.swapchain.is_srgb())?;
        self.resized = false;
        Ok(())
    }

    fn draw(&mut self) -> Result<()> {
        if self.resized {
            self.recreate()?;
        }
        let index = match self.swapchain.acquire()? {
            Acquired::Image(i) => i,
            Acquired::OutOfDate => {
                self.resized = true;
                return Ok(());
            }
        };
        if self.frames > 0 {
            self.gpu_ms = self.timestamps.elapsed_ms(0, 1)?;
        }
        self.orbit.apply(&mut self.camera);
        self.pass.update(&self.frame, &self.gpu_mesh, &self.camera, &self.light, self.base_color)?;
        let (w, h) = (self.swapchain.extent.width, self.swapchain.extent.height);
        let presented = self.swapchain.submit_and_present(index, |rec, image, view| {
            rec.reset_timestamps(&self.timestamps);
            rec.timestamp(&self.timestamps, 0);
            self.pass.record(rec, &self.target, &self.gpu_mesh, &self.frame);
            rec.timestamp(&self.timestamps, 1);
            self.tonemap.record(rec, &self.target, &DisplayImage { image, view, width: w, height: h }, self.exposure);
        })?;
        if !presented {
            self.resized = true;
        }
        self.frames += 1;
        self.window.set_title(&format!("fabric view — GPU {:.2} ms — exposure {:.2} — {}", self.gpu_ms, self.exposure, self.device.info().name));
        Ok(())
    }

    /// Reads the last frame's linear image back.
    fn screenshot(&self) -> Result<fabric_runtime::image::Image> {
        self.device.wait_idle()?;
        self.device.record_and_run("screenshot", |rec| self.target.record_readback_from(rec, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL))?;
        Ok(self.target.to_image()?)
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        // The last frame may still be in flight: let it finish before the fields (its
        // pipelines, images and buffers) are destroyed.
        let _ = self.device.wait_idle();
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
            WindowEvent::Resized(_) => v.resized = true,
            WindowEvent::RedrawRequested => {
                if let Err(e) = v.draw() {
                    return self.fail(event_loop, e);
                }
                if self.args.frames.is_some_and(|n| v.frames >= n) {
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
                            if let Light::Directional { dir_to_light, .. } = &mut v.light {
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
    let mesh = Mesh::by_name(args.scene.mesh.as_deref().unwrap_or("sphere"))?;
    let event_loop = EventLoop::new().map_err(|e| anyhow!("cannot connect to the window system ({e}); is DISPLAY set? for headless use: Xvfb :99 & DISPLAY=:99"))?;
    let mut app = App { args, mesh, viewer: None, error: None, dragging: None, cursor: None };
    event_loop.run_app(&mut app).context("window event loop")?;
    if let Some(e) = app.error.take() {
        return Err(e);
    }
    let viewer = app.viewer.take().context("the window never opened")?;
    if let Some(path) = &app.args.screenshot {
        viewer.screenshot()?.write(path, viewer.exposure)?;
        println!("wrote {}", path.display());
    }
    println!("{} frames, last GPU frame time {:.3} ms on {}", viewer.frames, viewer.gpu_ms, viewer.device.info().name);
    let device = viewer.device.clone();
    drop(viewer); // destruction can report validation errors too
    let errors = device.validation_errors();
    if !errors.is_empty() {
        anyhow::bail!("{} Vulkan validation error(s); first: {}", errors.len(), errors[0]);
    }
    Ok(())
}
