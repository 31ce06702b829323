//! The viewer's window (winit 0.30): events to [`Session`] moves, a frame per redraw.

use std::sync::Arc;

use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, KeyEvent, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

use super::{Session, SourceSpec, ViewOptions};
use crate::error::{Error, Result};
use crate::gpu::{Gpu, backend_tries, instance};

/// A window, its wgpu surface and the session drawn into it.
struct Open {
    session: Session,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    window: Arc<Window>,
    cursor: (f64, f64),
    dragging: bool,
}

struct App {
    spec: Option<SourceSpec>,
    options: ViewOptions,
    open: Option<Open>,
    error: Option<Error>,
    summary: Option<String>,
}

/// A device that can draw to `window`, and the window's surface.
fn gpu_for(window: Arc<Window>) -> Result<(Gpu, wgpu::Surface<'static>)> {
    let mut failure = String::from("no adapter");
    for backends in backend_tries() {
        let instance = instance(backends);
        let surface = match instance.create_surface(window.clone()) {
            Ok(s) => s,
            Err(e) => {
                failure = e.to_string();
                continue;
            }
        };
        match pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            compatible_surface: Some(&surface),
            ..Default::default()
        })) {
            Ok(adapter) => return Ok((Gpu::from_adapter(adapter)?, surface)),
            Err(e) => failure = e.to_string(),
        }
    }
    Err(Error::Gpu(format!(
        "no GPU adapter can draw to a window ({failure}); install a Vulkan driver (on Debian, mesa-vulkan-drivers for software rendering), or use `headless`"
    )))
}

impl App {
    fn start(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let attributes = Window::default_attributes()
            .with_title("surftile view")
            .with_inner_size(PhysicalSize::new(self.options.width, self.options.height));
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .map_err(|e| Error::Gpu(format!("could not open a window: {e}")))?,
        );
        let (gpu, surface) = gpu_for(window.clone())?;
        let size = window.inner_size();
        let caps = surface.get_capabilities(&gpu.adapter);
        // A linear (non-sRGB) format shows the grey levels the screenshot holds.
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| !f.is_srgb())
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| Error::Gpu("the window's surface offers no format".into()))?;
        let mut config = surface
            .get_default_config(&gpu.adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| Error::Gpu("the adapter cannot draw to this window".into()))?;
        config.format = format;
        config.present_mode = wgpu::PresentMode::AutoNoVsync;
        surface.configure(&gpu.device, &config);
        let mut options = self.options.clone();
        (options.width, options.height) = (config.width.max(16), config.height.max(16));
        let spec = self.spec.take().expect("started once");
        eprintln!("view: drawing on {}", gpu.describe());
        let session = Session::new(gpu, spec, options)?;
        window.set_title(&session.title());
        window.request_redraw();
        self.open = Some(Open {
            session,
            surface,
            config,
            window,
            cursor: (0.0, 0.0),
            dragging: false,
        });
        Ok(())
    }

    /// Draws one frame (after the next scripted step); returns true to close.
    fn redraw(&mut self) -> Result<bool> {
        let Some(o) = self.open.as_mut() else {
            return Ok(false);
        };
        if o.session.script_step()? {
            return Ok(true);
        }
        let texture = match o.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                o.surface.configure(&o.session.gpu().device, &o.config);
                return Ok(false);
            }
            // Minimised or busy: draw the frame off screen so scripts still advance.
            _ => {
                o.session.frame(None)?;
                return Ok(o.session.finished());
            }
        };
        let view = texture.texture.create_view(&Default::default());
        o.session.frame(Some((&view, o.config.format)))?;
        o.window.pre_present_notify();
        o.session.gpu().queue.present(texture);
        o.window.set_title(&o.session.title());
        Ok(o.session.finished())
    }

    fn key(&mut self, event: &KeyEvent) -> Result<bool> {
        let Some(o) = self.open.as_mut() else {
            return Ok(false);
        };
        if event.state != ElementState::Pressed {
            return Ok(false);
        }
        let (w, h) = (o.config.width as f64, o.config.height as f64);
        let s = &mut o.session;
        match &event.logical_key {
            Key::Named(NamedKey::ArrowLeft) => s.pan(-w / 8.0, 0.0),
            Key::Named(NamedKey::ArrowRight) => s.pan(w / 8.0, 0.0),
            Key::Named(NamedKey::ArrowUp) => s.pan(0.0, -h / 8.0),
            Key::Named(NamedKey::ArrowDown) => s.pan(0.0, h / 8.0),
            Key::Named(NamedKey::Escape) => return Ok(true),
            Key::Character(c) => match c.as_str() {
                "q" => return Ok(true),
                "+" | "=" => s.zoom(1.25, w / 2.0, h / 2.0),
                "-" => s.zoom(0.8, w / 2.0, h / 2.0),
                "s" => s.set_seed(s.seed().wrapping_add(1))?,
                "S" => s.set_seed(s.seed().wrapping_sub(1))?,
                "h" => s.toggle_shading(),
                "m" => s.show(super::Mode::Mask),
                "l" => {
                    let (az, el) = s.light();
                    s.set_light(az + 30.0, el);
                }
                "k" => {
                    let (az, el) = s.light();
                    s.set_light(az, if el >= 85.0 { 15.0 } else { el + 15.0 });
                }
                _ => {}
            },
            _ => {}
        }
        Ok(false)
    }

    fn event(&mut self, event: WindowEvent) -> Result<bool> {
        match event {
            WindowEvent::CloseRequested | WindowEvent::Destroyed => return Ok(true),
            WindowEvent::RedrawRequested => return self.redraw(),
            WindowEvent::KeyboardInput { event, .. } => return self.key(&event),
            _ => {}
        }
        let Some(o) = self.open.as_mut() else {
            return Ok(false);
        };
        match event {
            WindowEvent::Resized(size) if size.width >= 16 && size.height >= 16 => {
                o.config.width = size.width;
                o.config.height = size.height;
                o.surface.configure(&o.session.gpu().device, &o.config);
                let device = o.session.gpu().device.clone();
                o.session.renderer.resize(&device, size.width, size.height);
            }
            WindowEvent::CursorMoved { position, .. } => {
                let (x, y) = (position.x, position.y);
                if o.dragging {
                    o.session.pan(o.cursor.0 - x, o.cursor.1 - y);
                }
                o.cursor = (x, y);
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => o.dragging = state == ElementState::Pressed,
            WindowEvent::MouseWheel { delta, .. } => {
                let notches = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y as f64,
                    MouseScrollDelta::PixelDelta(p) => p.y / 50.0,
                };
                o.session
                    .zoom(1.25f64.powf(notches), o.cursor.0, o.cursor.1);
            }
            _ => {}
        }
        Ok(false)
    }

    fn close(&mut self, event_loop: &ActiveEventLoop) {
        if let Some(o) = self.open.take() {
            if self.error.is_none()
                && let Err(e) = o.session.screenshot()
            {
                self.error = Some(e);
            }
            self.summary = Some(o.session.summary());
            // The session (and its page workers, joined on drop) goes before the window.
            drop(o);
        }
        event_loop.exit();
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.open.is_some() || self.spec.is_none() {
            return;
        }
        if let Err(e) = self.start(event_loop) {
            self.error = Some(e);
            event_loop.exit();
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        match self.event(event) {
            Ok(false) => {}
            Ok(true) => self.close(event_loop),
            Err(e) => {
                self.error = Some(e);
                self.close(event_loop);
            }
        }
    }

    fn about_to_wait(&mut self, _: &ActiveEventLoop) {
        if let Some(o) = &self.open {
            o.window.request_redraw();
        }
    }
}

/// Opens the window and runs until it is closed (or the script and frame count end).
pub fn run(spec: SourceSpec, options: ViewOptions) -> Result<()> {
    let event_loop = EventLoop::new().map_err(|e| {
        Error::Gpu(format!(
            "could not open a window ({e}); set DISPLAY or WAYLAND_DISPLAY, or use `headless`"
        ))
    })?;
    let mut app = App {
        spec: Some(spec),
        options,
        open: None,
        error: None,
        summary: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| Error::Gpu(format!("the window's event loop failed: {e}")))?;
    if let Some(s) = &app.summary {
        eprintln!("view: {s}");
    }
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}
