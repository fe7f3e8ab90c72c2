//! The window and its events (winit 0.30's `ApplicationHandler`), one frame per redraw.
//!
//! A frame: apply the held keys to the camera, render with the chosen method into the
//! framebuffer (on the rayon pool, so the many parallel steps of a frame do not each hand
//! work over from a thread outside it), add the view's extras (boxes, wireframe, a pyramid
//! level), write the view into softbuffer's buffer, draw the readout over it, present.
//! Redraws are asked for only while something changes (keys held, the mouse looking, a
//! resize, a toggle, the scene's animations playing), so an idle viewer costs nothing.
//!
//! Animated scenes (`city+traffic:N`, glTF animations) play in real time: each frame poses
//! the scene at its time (the engine's `World` then brings the culler and the ray caster up
//! to date), Space pauses and resumes.
//!
//! Screenshots read the window's pixels back from the X server (`Surface::fetch`, an X11
//! GetImage); should that fail, the buffer just presented is saved instead, and the message
//! says so.

use std::num::NonZeroU32;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};
use glam::Vec3;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{DeviceEvent, DeviceId, ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{CursorGrabMode, Window, WindowId};

use crate::engine::{
    self, ClassifiedBoxes, Engine, Exact, FrameInfo, Framebuffer, LevelImage, Method, Pose, StartView,
};
use crate::fly::Fly;
use crate::views::{self, View};
use crate::Args;

/// Opens the window and runs until it is closed (or the screenshot is taken).
pub fn run(args: Args) -> Result<()> {
    let set = |v: &str| std::env::var_os(v).is_some_and(|s| !s.is_empty());
    if !set("DISPLAY") {
        if set("WAYLAND_DISPLAY") {
            bail!("no X display: DISPLAY is not set (the viewer opens an X11 window; start XWayland or run it under xvfb-run)");
        }
        bail!("no display: DISPLAY is not set, so there is no window to open (run it on a desktop, or under xvfb-run)");
    }
    let event_loop = EventLoop::new().map_err(|e| anyhow!("cannot open a window on display {:?}: {e}", display()))?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.map_or(0, usize::from))
        .build()
        .context("starting the thread pool")?;
    eprintln!("loading {} ...", engine::describe(&args.scene));
    let engine = Engine::load(&args.scene, &args.allow_asset_roots)?;
    let (w, h) = args.size;
    let aspect = w as f32 / h as f32;
    let start = start_view(&engine, &args, aspect)?;
    engine.camera(&start.pose, aspect).context("the start camera")?;
    let fly = Fly::new(start.pose, engine.ground(), engine.eye_height(), engine.base_speed());
    eprintln!("{} triangles; keys: `viewer --help`", engine.triangles());
    let mut app = App::new(args, engine, fly, start, pool);
    event_loop.run_app(&mut app).map_err(|e| anyhow!("the window's event loop failed: {e}"))?;
    app.report();
    match app.error.take() {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// The start view the options choose (`--camera`, `--path --frame`, `--eye --target`, or
/// none: [`Engine::start_pose`]), as `sightline render` reads the same options.
fn start_view(engine: &Engine, args: &Args, aspect: f32) -> Result<StartView> {
    let (near, far) = (args.near, args.far);
    if let Some(n) = args.file_camera {
        let (_, pose) = engine.file_camera(n, aspect)?;
        return Ok(StartView { pose, exact: Exact::File(n) });
    }
    let key = match (&args.path, args.eye, args.target) {
        (Some(path), _, _) => {
            let keys = sightline::scene::path::read_path(path)?;
            let mut key = *keys
                .get(args.frame)
                .with_context(|| format!("--frame {} but the path has {} frames", args.frame, keys.len()))?;
            key.near = near.unwrap_or(key.near);
            key.far = far.unwrap_or(key.far);
            key
        }
        (None, Some(eye), Some(target)) => {
            engine.key_like_render(eye, target, args.up.unwrap_or(Vec3::Y), args.fov, near, far)
        }
        _ => {
            let mut pose = engine.start_pose(aspect)?;
            pose.near = near.unwrap_or(pose.near);
            pose.far = far.unwrap_or(pose.far);
            return Ok(StartView { pose, exact: Exact::Pose });
        }
    };
    key.camera(aspect).context("the start camera")?;
    Ok(StartView { pose: Pose::from_key(&key), exact: Exact::Key(key) })
}

fn display() -> String {
    std::env::var("DISPLAY").unwrap_or_default()
}

/// The window and what presents into it.
struct Gfx {
    window: Rc<Window>,
    surface: softbuffer::Surface<Rc<Window>, Rc<Window>>,
}

struct App {
    args: Args,
    engine: Engine,
    pool: rayon::ThreadPool,
    gfx: Option<Gfx>,
    fb: Option<Framebuffer>,
    fly: Fly,
    /// The view the options named (drawn exactly until the first move).
    start: StartView,
    method: Method,
    view: View,
    level: usize,
    wire: bool,
    hud: bool,
    /// The culling view's boxes, kept while frozen (K).
    frozen: Option<ClassifiedBoxes>,
    freeze_next: bool,
    box_counts: Option<[usize; 3]>,
    captured: bool,
    dragging: bool,
    dirty: bool,
    frames: u32,
    last_tick: Instant,
    last_frame_ms: f64,
    fps: f64,
    info: FrameInfo,
    /// Render and whole-frame milliseconds per method, for the summary at exit.
    times: Vec<(Method, f64, f64)>,
    key_shot: bool,
    shot_tries: u32,
    /// Animation time (seconds) and whether it runs; `None` for a scene without animations.
    anim: Option<(f32, bool)>,
    error: Option<anyhow::Error>,
}

impl App {
    fn new(args: Args, engine: Engine, fly: Fly, start: StartView, pool: rayon::ThreadPool) -> App {
        let anim = engine.animated().then_some((args.time, !args.paused));
        App {
            method: args.method,
            view: args.view,
            wire: args.wireframe,
            hud: !args.no_hud,
            args,
            engine,
            pool,
            gfx: None,
            fb: None,
            fly,
            start,
            level: 3,
            frozen: None,
            freeze_next: false,
            box_counts: None,
            captured: false,
            dragging: false,
            dirty: true,
            frames: 0,
            last_tick: Instant::now(),
            last_frame_ms: 0.0,
            fps: 0.0,
            info: FrameInfo::default(),
            times: Vec::new(),
            key_shot: false,
            shot_tries: 0,
            anim,
            error: None,
        }
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: anyhow::Error) {
        self.error.get_or_insert(e);
        event_loop.exit();
    }

    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let (w, h) = self.args.size;
        let attrs = Window::default_attributes()
            .with_title(format!("sightline viewer: {}", engine::describe(&self.args.scene)))
            .with_inner_size(PhysicalSize::new(w, h));
        let window = Rc::new(event_loop.create_window(attrs).context("creating the window")?);
        let context = softbuffer::Context::new(window.clone())
            .map_err(|e| anyhow!("connecting softbuffer to the display: {e}"))?;
        let surface = softbuffer::Surface::new(&context, window.clone())
            .map_err(|e| anyhow!("creating the window's pixel surface: {e}"))?;
        window.request_redraw();
        self.gfx = Some(Gfx { window, surface });
        Ok(())
    }

    /// The far plane follows the eye once it moves (the start camera keeps its own).
    fn moved(&mut self) {
        self.fly.pose.far = self.fly.start.far.max(self.engine.far_for(self.fly.pose.eye));
        self.dirty = true;
    }

    fn frame(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let Some(size) = self.gfx.as_ref().map(|g| g.window.inner_size()) else { return Ok(()) };
        let (Some(nw), Some(nh)) = (NonZeroU32::new(size.width), NonZeroU32::new(size.height)) else {
            return Ok(()); // minimized
        };
        let (w, h) = (size.width.min(8192), size.height.min(8192));
        let now = Instant::now();
        let dt = (now - self.last_tick).as_secs_f64();
        self.last_tick = now;
        if self.frames > 0 {
            self.fps = if self.fps == 0.0 { 1.0 / dt.max(1e-6) } else { 0.9 * self.fps + 0.1 / dt.max(1e-6) };
        }
        if self.fly.update(dt.min(0.1) as f32) {
            self.moved();
        }
        if let Some((t, playing)) = &mut self.anim {
            if *playing && self.frames > 0 {
                *t += dt.min(0.1) as f32;
            }
            self.engine.animate(*t)?;
        }
        let mut fb = match self.fb.take() {
            Some(fb) if fb.width() == w && fb.height() == h => fb,
            _ => Framebuffer::new(w, h)?,
        };
        let counting = self.view == View::Complexity;
        if fb.depth_tests.is_some() != counting {
            fb.count_depth_tests(counting);
        }
        let aspect = w as f32 / h as f32;
        let camera = if self.fly.pose == self.fly.start {
            // The camera the options named, exactly, until the first move (R returns to it).
            self.engine.start_camera(&self.start, aspect)?
        } else {
            self.engine.camera(&self.fly.pose, aspect)?
        };
        let t0 = Instant::now();
        let (level, ms_render) = self.draw(&camera, &mut fb)?;
        let lines = if self.hud { readout(self, ms_render, level.as_ref()) } else { Vec::new() };
        let shot_due = self.key_shot || self.args.screenshot.is_some() && self.frames + 1 >= self.args.after_frames;
        let gfx = self.gfx.as_mut().expect("checked above");
        gfx.surface.resize(nw, nh).map_err(|e| anyhow!("resizing the window's surface: {e}"))?;
        let mut buffer = gfx.surface.buffer_mut().map_err(|e| anyhow!("the window's buffer: {e}"))?;
        views::compose(self.view, &fb, level.as_ref(), &mut buffer);
        sightline::hud::draw(&mut buffer, w, h, &lines, if w >= 1800 { 2 } else { 1 });
        let presented = shot_due.then(|| buffer.to_vec());
        buffer.present().map_err(|e| anyhow!("presenting the frame: {e}"))?;
        self.fb = Some(fb);
        self.frames += 1;
        self.last_frame_ms = t0.elapsed().as_secs_f64() * 1e3;
        self.times.push((self.method, self.info.ms, self.last_frame_ms));
        self.dirty = false;
        if let Some(presented) = presented {
            self.shoot(event_loop, &presented, w, h)?;
        }
        Ok(())
    }

    /// Renders the frame and the view's extras into `fb` on the thread pool; returns the
    /// pyramid level for the hzb view and the milliseconds it all took.
    fn draw(&mut self, camera: &engine::Camera, fb: &mut Framebuffer) -> Result<(Option<LevelImage>, f64)> {
        let t0 = Instant::now();
        let (w, h) = (fb.width(), fb.height());
        let (engine, view, method, wire) = (&mut self.engine, self.view, self.method, self.wire);
        let (frozen, freeze_next, level) = (&mut self.frozen, std::mem::take(&mut self.freeze_next), self.level);
        type Drawn = (FrameInfo, Option<LevelImage>, Option<[usize; 3]>);
        let (info, level, counts) = self.pool.install(|| -> Result<Drawn> {
            let info = engine.render(camera, method, fb)?;
            let (mut level_image, mut counts) = (None, None);
            match view {
                View::Culling => {
                    if freeze_next {
                        *frozen = match frozen {
                            Some(_) => None,
                            None => Some(engine.classify_clusters(camera, w, h)?),
                        };
                    }
                    let fresh;
                    let boxes = match frozen.as_ref() {
                        Some(b) => b,
                        None => {
                            fresh = engine.classify_clusters(camera, w, h)?;
                            &fresh
                        }
                    };
                    views::dim(fb);
                    engine.draw_boxes(camera, fb, boxes);
                    counts = Some(boxes.counts());
                }
                View::Hzb => level_image = Some(Engine::pyramid_level(fb, level)),
                _ => {}
            }
            if wire && matches!(view, View::Color | View::Culling) {
                engine.draw_visible_edges(camera, fb)?;
            }
            Ok((info, level_image, counts))
        })?;
        if let Some(l) = &level {
            self.level = l.level;
        }
        self.info = info;
        self.box_counts = counts;
        Ok((level, t0.elapsed().as_secs_f64() * 1e3))
    }

    /// Saves the window's pixels: for `--screenshot` (then exits), or for the key.
    fn shoot(&mut self, event_loop: &ActiveEventLoop, presented: &[u32], w: u32, h: u32) -> Result<()> {
        let gfx = self.gfx.as_mut().expect("a frame was just presented");
        let (pixels, source) = match gfx.surface.fetch() {
            Ok(p) if p.len() == presented.len() => (p, "read back from the window".to_string()),
            other => {
                let why = match other {
                    Ok(p) => format!("{} pixels for a {w}x{h} window", p.len()),
                    Err(e) => e.to_string(),
                };
                if self.shot_tries < 20 {
                    // The window may not be mapped yet: try again after the next frame.
                    self.shot_tries += 1;
                    self.dirty = true;
                    return Ok(());
                }
                (presented.to_vec(), format!("the buffer presented (the window could not be read back: {why})"))
            }
        };
        self.shot_tries = 0;
        let path = match (self.key_shot, &self.args.screenshot) {
            (false, Some(p)) => p.clone(),
            _ => next_free("viewer", "png"),
        };
        save_png(&path, &pixels, w, h)?;
        eprintln!("screenshot {} ({w}x{h}, {source})", path.display());
        if !self.key_shot {
            event_loop.exit();
        }
        self.key_shot = false;
        Ok(())
    }

    fn key(&mut self, event_loop: &ActiveEventLoop, code: KeyCode, down: bool, repeat: bool) {
        let held = &mut self.fly.held;
        match code {
            KeyCode::KeyW => held.forward = down,
            KeyCode::KeyS => held.back = down,
            KeyCode::KeyA => held.left = down,
            KeyCode::KeyD => held.right = down,
            KeyCode::KeyQ => held.down = down,
            KeyCode::KeyE => held.up = down,
            KeyCode::ArrowLeft => held.turn_left = down,
            KeyCode::ArrowRight => held.turn_right = down,
            KeyCode::ArrowUp => held.turn_up = down,
            KeyCode::ArrowDown => held.turn_down = down,
            KeyCode::ShiftLeft | KeyCode::ShiftRight => held.fast = down,
            KeyCode::ControlLeft | KeyCode::ControlRight => held.slow = down,
            _ => {}
        }
        self.dirty = true;
        if !down || repeat {
            return;
        }
        let digit = [KeyCode::Digit1, KeyCode::Digit2, KeyCode::Digit3, KeyCode::Digit4, KeyCode::Digit5];
        let pad = [KeyCode::Numpad1, KeyCode::Numpad2, KeyCode::Numpad3, KeyCode::Numpad4, KeyCode::Numpad5];
        if let Some(i) = digit.iter().position(|k| *k == code).or_else(|| pad.iter().position(|k| *k == code)) {
            self.method = Method::ALL[i];
            return;
        }
        match code {
            KeyCode::KeyV => self.view = self.view.step(if self.fly.held.fast { -1 } else { 1 }),
            KeyCode::Equal | KeyCode::NumpadAdd => self.level = (self.level + 1).min(16),
            KeyCode::Minus | KeyCode::NumpadSubtract => self.level = self.level.saturating_sub(1),
            KeyCode::KeyK => self.freeze_next = true,
            KeyCode::KeyL => self.wire = !self.wire,
            KeyCode::KeyH => self.hud = !self.hud,
            KeyCode::KeyG => {
                self.fly.toggle_walk();
                self.moved();
            }
            KeyCode::KeyC => self.capture(!self.captured),
            KeyCode::KeyR | KeyCode::Home => {
                self.fly.reset();
                self.moved();
            }
            KeyCode::F12 | KeyCode::KeyP => self.key_shot = true,
            KeyCode::Space => {
                if let Some((_, playing)) = &mut self.anim {
                    *playing = !*playing;
                }
            }
            KeyCode::Escape if self.captured => self.capture(false),
            KeyCode::Escape => event_loop.exit(),
            _ => {}
        }
    }

    fn capture(&mut self, on: bool) {
        let Some(gfx) = &self.gfx else { return };
        let w = &gfx.window;
        let grabbed = if on {
            w.set_cursor_grab(CursorGrabMode::Locked).or_else(|_| w.set_cursor_grab(CursorGrabMode::Confined))
        } else {
            w.set_cursor_grab(CursorGrabMode::None)
        };
        match grabbed {
            Ok(()) => {
                w.set_cursor_visible(!on);
                self.captured = on;
            }
            Err(e) => eprintln!("cannot capture the mouse ({e}); drag with a button held to look"),
        }
    }

    /// Frame times per method, printed when the window closes.
    fn report(&self) {
        for m in Method::ALL {
            let mut r: Vec<f64> = self.times.iter().filter(|t| t.0 == m).map(|t| t.1).collect();
            let mut f: Vec<f64> = self.times.iter().filter(|t| t.0 == m).map(|t| t.2).collect();
            if r.is_empty() {
                continue;
            }
            r.sort_by(f64::total_cmp);
            f.sort_by(f64::total_cmp);
            eprintln!(
                "{:<11} {:>5} frames, median render {:>7.2} ms, median frame {:>7.2} ms",
                m.name(),
                r.len(),
                r[r.len() / 2],
                f[f.len() / 2]
            );
        }
    }
}

/// The readout's lines.
fn readout(app: &App, ms_render: f64, level: Option<&LevelImage>) -> Vec<String> {
    let i = &app.info;
    let p = &app.fly.pose;
    let mut view = app.view.name().to_string();
    if let Some(l) = level {
        view += &format!(" {}/{} (+/-)", l.level, l.levels - 1);
    }
    let mut flags = String::new();
    for (on, name) in [(app.wire, "  wireframe"), (app.fly.walk, "  walk"), (app.frozen.is_some(), "  frozen")] {
        if on {
            flags += name;
        }
    }
    let mut lines = vec![
        format!("{}  {}{}", app.method.name(), view, flags),
        format!(
            "frame {:.1} ms  render {:.1} ms (engine {:.1})  {:.0} fps",
            app.last_frame_ms, ms_render, i.ms, app.fps
        ),
    ];
    if let Some([cull, draw, shading]) = i.stages {
        lines.push(format!("engine: cull {cull:.2} ms  draw {draw:.2} ms  shading {shading:.2} ms"));
    }
    match (i.triangles_drawn, i.clusters) {
        (Some(t), Some((drawn, all))) => {
            lines.push(format!(
                "triangles drawn {}  culled {}",
                thousands(t),
                thousands(app.engine.triangles().saturating_sub(t))
            ));
            lines.push(format!(
                "clusters drawn {}/{}  skipped: frustum {} back {} hidden {}",
                thousands(drawn),
                thousands(all),
                thousands(i.culled.0),
                thousands(i.culled.1),
                thousands(i.culled.2)
            ));
        }
        _ => lines.push(format!("ray casting: one ray per pixel, {} triangles", thousands(app.engine.triangles()))),
    }
    if let Some([out, hidden, visible]) = app.box_counts {
        lines.push(format!("boxes: outside {out} (blue)  hidden {hidden} (red)  visible {visible} (green)"));
    }
    lines.push(format!("eye {:.1}, {:.1}, {:.1}  speed {:.1}/s", p.eye.x, p.eye.y, p.eye.z, app.fly.speed));
    if let Some((t, playing)) = app.anim {
        lines.push(format!(
            "time {t:.2} s  {}",
            if playing { "playing (Space: pause)" } else { "paused (Space: play)" }
        ));
    }
    lines
}

fn thousands(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (k, c) in s.chars().enumerate() {
        if k > 0 && (s.len() - k).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// `stem-0001.ext`, the first number not taken in the current folder.
fn next_free(stem: &str, ext: &str) -> PathBuf {
    (1..).map(|n| PathBuf::from(format!("{stem}-{n:04}.{ext}"))).find(|p| !p.exists()).expect("some number is free")
}

/// Writes 0RGB words as an RGBA PNG.
fn save_png(path: &Path, pixels: &[u32], w: u32, h: u32) -> Result<()> {
    let rgba: Vec<u8> = pixels.iter().flat_map(|p| [(p >> 16) as u8, (p >> 8) as u8, *p as u8, 255]).collect();
    image::save_buffer(path, &rgba, w, h, image::ExtendedColorType::Rgba8)
        .with_context(|| format!("writing the screenshot {}", path.display()))
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_none() {
            if let Err(e) = self.open(event_loop) {
                self.fail(event_loop, e);
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.frame(event_loop) {
                    self.fail(event_loop, e);
                }
            }
            WindowEvent::Resized(_) => self.dirty = true,
            WindowEvent::Focused(false) => {
                self.fly.held = Default::default();
                self.dragging = false;
            }
            WindowEvent::KeyboardInput { event, .. } => {
                if let PhysicalKey::Code(code) = event.physical_key {
                    self.key(event_loop, code, event.state == ElementState::Pressed, event.repeat);
                }
            }
            WindowEvent::MouseInput { state, button: MouseButton::Left | MouseButton::Right, .. } => {
                self.dragging = state == ElementState::Pressed;
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let notches = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.fly.speed *= 1.25f32.powf(notches.clamp(-10.0, 10.0));
                self.dirty = true;
            }
            _ => {}
        }
    }

    fn device_event(&mut self, _: &ActiveEventLoop, _: DeviceId, event: DeviceEvent) {
        if let DeviceEvent::MouseMotion { delta: (dx, dy) } = event {
            if self.dragging || self.captured {
                self.fly.look(dx, dy);
                self.moved();
            }
        }
    }

    fn about_to_wait(&mut self, _: &ActiveEventLoop) {
        let pending = self.args.screenshot.is_some() || self.key_shot;
        if let Some(g) = &self.gfx {
            let playing = self.anim.is_some_and(|a| a.1);
            if self.dirty || pending || playing || self.fly.held.any() {
                g.window.request_redraw();
            }
        }
    }
}
