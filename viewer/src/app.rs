//! The eframe window: a 3-D view (egui painter triangles shaded on the CPU, back to front), a
//! lattice overlay, play / pause / scrub at the scene's fps, live mode (the simulation runs as
//! you watch and the mouse drives a capsule), a parameter panel that re-prepares the world, a
//! spring plot, and live reload. The logic it calls lives in the tested modules (`camera`,
//! `live`, `oscillator`, `raster::shade`); this file is wiring and drawing only.

use crate::camera::OrbitCamera;
use crate::live::{plan_steps, Gesture, LiveManipulator, StepPlan, StepTimer};
use crate::oscillator::SpringOscillator;
use crate::raster::{self, bounds_of, capsule_mesh, DrawMesh, BACKGROUND, CAPSULE_COLOUR};
use crate::reload::Reloader;
use crate::source::{Simulation, ViewSource};
use crate::{initial_camera, ViewArgs, ViewerError};
use eframe::egui;
use springbake_core::material::{Material, PRESETS};
use springbake_core::nalgebra::Vector3;
use springbake_core::plugin::Registry;
use springbake_core::scene::{CustomMaterial, MaterialSpec, ModelKind};
use std::path::PathBuf;
use std::time::Instant;

/// Open the window (blocks until it closes).
pub fn run(args: ViewArgs) -> Result<(), ViewerError> {
    if !args.input.exists() {
        return Err(ViewerError::Usage(format!(
            "{}: no such file",
            args.input.display()
        )));
    }
    let registry = springbake_pipeline::default_registry();
    // Open once before the window so a bad file is an error on the command line.
    let source = ViewSource::open(&registry, &args.input)?;
    let title = format!("springbake view: {}", args.input.display());
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title(title.clone())
            .with_inner_size([1200.0, 800.0]),
        ..Default::default()
    };
    eframe::run_native(
        &title,
        options,
        Box::new(move |cc| {
            let wake_ctx = cc.egui_ctx.clone();
            let reloader =
                Reloader::start(&args.input, Box::new(move || wake_ctx.request_repaint()));
            Ok(Box::new(ViewerApp::new(registry, args, source, reloader)))
        }),
    )
    .map_err(|e| ViewerError::Window(e.to_string()))
}

/// The panel's simulation parameters.
#[derive(Debug, Clone, PartialEq)]
struct Params {
    preset: String,
    damping: f64,
    cells: u32,
}

/// A parked live capsule far from everything: present from the first step so the world's
/// step bound already counts its contact layer.
const PARKED_M: f64 = 1.0e6;

struct LiveState {
    manipulator: LiveManipulator,
    reaction: Vector3<f64>,
    plan: Option<StepPlan>,
    steps_per_s: f64,
    last_step_s: f64,
    frame: usize,
}

struct ViewerApp {
    registry: Registry,
    input: PathBuf,
    source: Option<ViewSource>,
    error: Option<String>,
    params: Option<Params>,
    camera: OrbitCamera,
    /// Frames recorded so far (bodies and scripted capsules), 1-based frame `i` at `i - 1`.
    recorded: Vec<Vec<DrawMesh>>,
    frame: usize,
    playing: bool,
    frame_clock: f64,
    last_tick: Instant,
    show_lattice: bool,
    /// Mark where the floor, walls, capsules and colliders push the bodies.
    show_contacts: bool,
    live: Option<LiveState>,
    target_fps: f64,
    timer: StepTimer,
    ui_fps: f64,
    reloader: Reloader,
    /// `--live`: switch live mode on at the first frame.
    start_live: bool,
    /// `--trace`: one JSON line per drawn frame.
    trace: Option<std::io::BufWriter<std::fs::File>>,
    opened: Instant,
}

fn params_of(sim: &Simulation) -> Params {
    let body = &sim.loaded.scene.body[0];
    let material = body.material.resolve().unwrap_or_else(|_| Material {
        name: "rubber".into(),
        young_pa: 1.5e6,
        poisson: 0.47,
        density_kg_m3: 1100.0,
        damping_ratio: 0.05,
    });
    let cells = sim
        .prepared
        .bodies
        .first()
        .and_then(|b| b.lattice.dims.iter().copied().max())
        .filter(|&n| n > 0)
        .unwrap_or(10);
    let preset = match &body.material {
        MaterialSpec::Preset(p) => Material::preset(p)
            .map(|m| m.name)
            .unwrap_or_else(|_| p.clone()),
        MaterialSpec::Custom(_) => "custom".into(),
    };
    Params {
        preset,
        damping: material.damping_ratio,
        cells,
    }
}

fn park(sim: &mut Simulation) {
    let up = sim.up();
    let mut m = live_manipulator_for(sim);
    m.centre = up * PARKED_M;
    sim.prepared.world.live_capsules = vec![m.capsule()];
}

fn live_manipulator_for(sim: &Simulation) -> LiveManipulator {
    let meshes = sim.body_meshes();
    let (lo, hi) = bounds_of(meshes.iter().flat_map(|m| m.positions.iter())).unwrap_or_default();
    let young = sim
        .prepared
        .bodies
        .iter()
        .map(|b| b.material.young_pa)
        .fold(0.0, f64::max);
    LiveManipulator::above(lo, hi, sim.up(), young)
}

impl ViewerApp {
    fn new(
        registry: Registry,
        args: ViewArgs,
        source: ViewSource,
        reloader: Reloader,
    ) -> ViewerApp {
        let mut app = ViewerApp {
            registry,
            input: args.input,
            source: None,
            error: None,
            params: None,
            camera: OrbitCamera::new(Vector3::zeros(), Vector3::y(), 3.0),
            recorded: Vec::new(),
            frame: args.frame.max(1),
            playing: false,
            frame_clock: 0.0,
            last_tick: Instant::now(),
            show_lattice: false,
            show_contacts: false,
            live: None,
            target_fps: 30.0,
            timer: StepTimer::default(),
            ui_fps: 0.0,
            reloader,
            start_live: args.live,
            trace: args
                .trace
                .as_ref()
                .and_then(|p| std::fs::File::create(p).ok())
                .map(std::io::BufWriter::new),
            opened: Instant::now(),
        };
        app.install(source, true);
        app
    }

    /// One `--trace` line for the frame just drawn.
    fn write_trace(&mut self, view: egui::Rect, pixels_per_point: f32, meshes: &[DrawMesh]) {
        use std::io::Write;
        let Some(out) = self.trace.as_mut() else {
            return;
        };
        let up = self.camera.up;
        let count = self.source.as_ref().map_or(0, ViewSource::body_count);
        let bodies = || meshes.iter().take(count).flat_map(|m| m.positions.iter());
        let top = bodies()
            .map(|p| up.dot(p))
            .fold(f64::NEG_INFINITY, f64::max);
        // The bodies' top under the live capsule (within its radius of its axis, seen from
        // above: where it presses). A reach of half its length all round took in the undented
        // top beside it, so a capsule 4 cm into a block read a 4–5 mm dent.
        let under = self.live.as_ref().map(|l| {
            let c = l.manipulator.capsule();
            bodies()
                .filter(|p| {
                    let d = *p - c.centre;
                    let flat = d - up * up.dot(&d);
                    let along = flat.dot(&c.axis).clamp(-0.5 * c.length, 0.5 * c.length);
                    (flat - c.axis * along).norm() <= c.radius
                })
                .map(|p| up.dot(p))
                .fold(f64::NEG_INFINITY, f64::max)
        });
        let centre = view.center() * pixels_per_point;
        let capsule = self.live.as_ref().map(|l| up.dot(&l.manipulator.centre));
        let line = serde_json::json!({
            "capsule_height": capsule,
            "t": self.opened.elapsed().as_secs_f64(),
            "ui_fps": self.ui_fps,
            "live": self.live.is_some(),
            "frame": self.frame,
            "body_top": top.is_finite().then_some(top),
            "top_under_capsule": under.filter(|u| u.is_finite()),
            "view_centre": [centre.x, centre.y],
        });
        let _ = writeln!(out, "{line}").and_then(|()| out.flush());
    }

    /// Show a freshly opened source: park the live capsule, record frame 1, frame the camera.
    fn install(&mut self, mut source: ViewSource, reframe: bool) {
        if let ViewSource::Simulated(sim) = &mut source {
            park(sim);
            if self.params.is_none() {
                self.params = Some(params_of(sim));
            }
        } else {
            self.params = None;
        }
        self.recorded.clear();
        self.live = None;
        self.error = None;
        match Self::frame_meshes(&mut source, 1) {
            Ok(m) => {
                if reframe {
                    self.camera = initial_camera(&source);
                }
                self.recorded.push(m);
            }
            Err(e) => self.error = Some(e.to_string()),
        }
        let want = self.frame.min(source.frame_count()).max(1);
        self.source = Some(source);
        self.frame = 1;
        self.seek(want);
    }

    fn frame_meshes(source: &mut ViewSource, frame: usize) -> Result<Vec<DrawMesh>, ViewerError> {
        match source {
            ViewSource::Simulated(sim) => {
                sim.advance_to(frame)?;
                let mut out = sim.body_meshes();
                let w = &sim.prepared.world;
                out.extend(
                    w.manipulators
                        .iter()
                        .map(|m| capsule_mesh(&m.capsule_at(w.time), 24, 6, CAPSULE_COLOUR)),
                );
                out.extend(sim.particle_mesh());
                Ok(out)
            }
            ViewSource::Baked(b) => Ok(b.meshes_at(frame)),
        }
    }

    /// Go to 1-based `frame`, simulating and recording the frames up to it.
    fn seek(&mut self, frame: usize) {
        let Some(source) = self.source.as_mut() else {
            return;
        };
        let frame = frame.clamp(1, source.frame_count().max(1));
        while self.recorded.len() < frame {
            match Self::frame_meshes(source, self.recorded.len() + 1) {
                Ok(m) => self.recorded.push(m),
                Err(e) => {
                    self.error = Some(e.to_string());
                    self.playing = false;
                    break;
                }
            }
        }
        self.frame = frame.min(self.recorded.len()).max(1);
    }

    /// Re-open the file (live reload) or re-prepare with the panel's parameters.
    fn reopen(&mut self, with_params: bool) {
        let opened = ViewSource::open(&self.registry, &self.input).and_then(|source| {
            match (source, with_params.then_some(self.params.clone()).flatten()) {
                (ViewSource::Simulated(sim), Some(p)) => {
                    let mut loaded = sim.loaded.clone();
                    drop(sim);
                    let base = Material::preset(&p.preset).ok();
                    for body in &mut loaded.scene.body {
                        let m = base.clone().or_else(|| body.material.resolve().ok());
                        if let Some(m) = m {
                            body.material = MaterialSpec::Custom(CustomMaterial {
                                young: m.young_pa,
                                density: m.density_kg_m3,
                                poisson: Some(m.poisson),
                                damping: Some(p.damping),
                            });
                        }
                        // Only lattices and plane slabs have a cell count (other cage
                        // models refuse `cells`).
                        if matches!(body.model, ModelKind::Lattice | ModelKind::Plane) {
                            body.cells = Some(p.cells);
                            body.cell_size = None;
                        }
                    }
                    Ok(ViewSource::Simulated(Box::new(Simulation::new(
                        &self.registry,
                        loaded,
                    )?)))
                }
                (s, _) => Ok(s),
            }
        });
        match opened {
            Ok(source) => {
                if !with_params {
                    self.params = None;
                }
                self.install(source, false);
            }
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    fn toggle_live(&mut self, on: bool) {
        if !on {
            self.live = None;
            self.reopen(self.params.is_some());
            return;
        }
        let Some(ViewSource::Simulated(sim)) = self.source.as_mut() else {
            return;
        };
        let manipulator = live_manipulator_for(sim);
        sim.prepared.world.live_capsules = vec![manipulator.capsule()];
        self.playing = false;
        self.live = Some(LiveState {
            manipulator,
            reaction: Vector3::zeros(),
            plan: None,
            steps_per_s: 0.0,
            last_step_s: 0.0,
            frame: sim.frame,
        });
    }

    /// One live-mode frame: plan steps (eq 7–8), move the capsule against the last reaction,
    /// step, and return what to draw.
    fn live_step(&mut self, gestures: &[Gesture]) -> Option<Vec<DrawMesh>> {
        let t_i = 1.0 / self.target_fps;
        let live = self.live.as_mut()?;
        let Some(ViewSource::Simulated(sim)) = self.source.as_mut() else {
            return None;
        };
        let world = &mut sim.prepared.world;
        let fixed = world.settings.fixed_substeps.take();
        let max_dt = world.choose_substeps(t_i).dt;
        let plan = plan_steps(t_i, &self.timer, max_dt, 20_000);
        live.manipulator.update(gestures, live.reaction, t_i);
        world.live_capsules = vec![live.manipulator.capsule()];
        world.settings.fixed_substeps = Some(plan.steps);
        live.frame += 1;
        let t0 = Instant::now();
        let result = world.advance_frame(plan.steps as f64 * plan.dt, live.frame, &|| false);
        let step_s = t0.elapsed().as_secs_f64();
        world.settings.fixed_substeps = fixed;
        match result {
            Ok(d) => live.reaction = d.reaction(),
            Err(e) => {
                self.error = Some(format!("{e}; toggle live mode off to start again"));
                return None;
            }
        }
        self.timer.record_steps(plan.steps, step_s);
        live.plan = Some(plan);
        live.last_step_s = step_s;
        live.steps_per_s = 0.8 * live.steps_per_s + 0.2 * (plan.steps as f64 * self.ui_fps);
        let mut meshes = sim.body_meshes();
        let w = &sim.prepared.world;
        meshes.extend(
            w.manipulators
                .iter()
                .map(|m| capsule_mesh(&m.capsule_at(w.time), 24, 6, CAPSULE_COLOUR)),
        );
        meshes.push(capsule_mesh(
            &live.manipulator.capsule(),
            24,
            6,
            CAPSULE_COLOUR,
        ));
        Some(meshes)
    }

    fn side_panel(&mut self, ui: &mut egui::Ui) {
        ui.heading("springbake");
        ui.label(self.input.display().to_string());
        ui.separator();
        let simulated = matches!(self.source, Some(ViewSource::Simulated(_)));
        ui.checkbox(&mut self.show_lattice, "lattice overlay");
        ui.checkbox(&mut self.show_contacts, "contact overlay");
        if simulated {
            let mut live_on = self.live.is_some();
            if ui
                .checkbox(&mut live_on, "live mode (mouse drives a capsule)")
                .changed()
            {
                self.toggle_live(live_on);
            }
            ui.add(egui::Slider::new(&mut self.target_fps, 10.0..=120.0).text("target fps"));
            if self.live.is_some() {
                ui.label("drag: move in the horizontal plane\nshift-drag or wheel: height\nright-drag: yaw\nmiddle-drag: orbit, ctrl-wheel: zoom");
            }
        }
        ui.separator();
        let mut reprepare = false;
        if let Some(p) = self.params.as_mut() {
            ui.label("parameters (re-prepare on change)");
            let before = p.preset.clone();
            egui::ComboBox::from_label("material")
                .selected_text(p.preset.clone())
                .show_ui(ui, |ui| {
                    for preset in PRESETS {
                        ui.selectable_value(&mut p.preset, preset.0.to_string(), preset.0);
                    }
                });
            if p.preset != before {
                if let Ok(m) = Material::preset(&p.preset) {
                    p.damping = m.damping_ratio;
                }
                reprepare = true;
            }
            let r = ui.add(egui::Slider::new(&mut p.damping, 0.0..=1.5).text("damping ratio"));
            reprepare |= r.drag_stopped() || (r.changed() && !r.dragged());
            let r = ui.add(egui::Slider::new(&mut p.cells, 2..=40).text("lattice cells"));
            reprepare |= r.drag_stopped() || (r.changed() && !r.dragged());
            ui.separator();
            self.spring_plot(ui);
        }
        if reprepare {
            self.reopen(true);
        }
    }

    fn spring_plot(&self, ui: &mut egui::Ui) {
        let (Some(p), Some(ViewSource::Simulated(sim))) = (&self.params, &self.source) else {
            return;
        };
        let Some(body) = sim.prepared.bodies.first() else {
            return;
        };
        let material = Material {
            damping_ratio: p.damping,
            ..body.material.clone()
        };
        let osc = SpringOscillator::for_lattice(&material, body.lattice.cell_size);
        ui.label(format!(
            "one spring: k = {:.3e} N/m, μ = {:.3e} kg\nω = {:.1} rad/s, period {:.2} ms, ζ = {:.2}",
            osc.k,
            osc.mass_kg,
            osc.omega(),
            osc.period() * 1e3,
            osc.zeta
        ));
        let (response, painter) = ui.allocate_painter(
            egui::vec2(ui.available_width().min(320.0), 120.0),
            egui::Sense::hover(),
        );
        let rect = response.rect;
        painter.rect_filled(rect, 2.0, egui::Color32::from_gray(24));
        painter.line_segment(
            [rect.left_center(), rect.right_center()],
            egui::Stroke::new(1.0, egui::Color32::from_gray(80)),
        );
        let samples = osc.samples(6.0, 300);
        let t_end = samples.last().map_or(1.0, |s| s.0);
        let points: Vec<egui::Pos2> = samples
            .iter()
            .map(|&(t, x)| {
                egui::pos2(
                    rect.left() + rect.width() * (t / t_end) as f32,
                    rect.center().y - 0.45 * rect.height() * x as f32,
                )
            })
            .collect();
        painter.add(egui::Shape::line(
            points,
            egui::Stroke::new(1.5, egui::Color32::from_rgb(240, 180, 90)),
        ));
        painter.text(
            rect.left_top() + egui::vec2(4.0, 2.0),
            egui::Align2::LEFT_TOP,
            "x(t) = e^(-ζωt) cos(ω_d t), 6 periods",
            egui::FontId::proportional(11.0),
            egui::Color32::GRAY,
        );
    }

    fn bottom_panel(&mut self, ui: &mut egui::Ui) {
        let Some(source) = &self.source else { return };
        let count = source.frame_count().max(1);
        let fps = source.fps();
        ui.horizontal(|ui| {
            let live = self.live.is_some();
            ui.add_enabled_ui(!live, |ui| {
                if ui
                    .button(if self.playing { "pause" } else { "play" })
                    .clicked()
                {
                    self.playing = !self.playing;
                    self.last_tick = Instant::now();
                }
                let mut f = self.frame;
                let r = ui.add(
                    egui::Slider::new(&mut f, 1..=count)
                        .text(format!("frame of {count} at {fps} fps")),
                );
                if r.changed() {
                    self.playing = false;
                    self.seek(f);
                }
            });
        });
    }

    /// Draw meshes, the lattice overlay, the floor grid and the status text into the 3-D view.
    fn draw_view(&self, painter: &egui::Painter, rect: egui::Rect, meshes: &[DrawMesh]) {
        painter.rect_filled(
            rect,
            0.0,
            egui::Color32::from_rgb(BACKGROUND[0], BACKGROUND[1], BACKGROUND[2]),
        );
        let (w, h) = (rect.width() as f64, rect.height() as f64);
        let proj = self.camera.projector(w, h);
        let to_pos = |p: &Vector3<f64>| {
            proj.project(p)
                .map(|s| rect.min + egui::vec2(s.x as f32, s.y as f32))
        };
        // Floor grid.
        if let Some(ViewSource::Simulated(sim)) = &self.source {
            if let Some(floor) = sim.prepared.floor {
                let up = self.camera.up;
                let a = if up.x.abs() < 0.9 {
                    Vector3::x()
                } else {
                    Vector3::z()
                };
                let a = (a - up * up.dot(&a)).normalize();
                let b = up.cross(&a);
                let centre = self.camera.target - up * up.dot(&self.camera.target) + up * floor;
                let half = self.camera.distance * 0.6;
                let stroke = egui::Stroke::new(1.0, egui::Color32::from_gray(70));
                for i in -10..=10 {
                    let o = half * i as f64 / 10.0;
                    for (u, v) in [(a, b), (b, a)] {
                        if let (Some(p), Some(q)) = (
                            to_pos(&(centre + u * o - v * half)),
                            to_pos(&(centre + u * o + v * half)),
                        ) {
                            painter.line_segment([p, q], stroke);
                        }
                    }
                }
            }
        }
        // Shaded triangles back to front.
        let mut tris = raster::shade(meshes, &self.camera, w, h);
        tris.sort_by(|x, y| {
            let dx: f64 = x.points.iter().map(|p| p.depth).sum();
            let dy: f64 = y.points.iter().map(|p| p.depth).sum();
            dy.total_cmp(&dx)
        });
        let mut mesh = egui::Mesh::default();
        mesh.reserve_vertices(tris.len() * 3);
        mesh.reserve_triangles(tris.len());
        for t in &tris {
            let colour = egui::Color32::from_rgb(t.colour[0], t.colour[1], t.colour[2]);
            let base = mesh.vertices.len() as u32;
            for p in &t.points {
                mesh.colored_vertex(rect.min + egui::vec2(p.x as f32, p.y as f32), colour);
            }
            mesh.add_triangle(base, base + 1, base + 2);
        }
        painter.add(egui::Shape::mesh(mesh));
        // Lattice overlay: the springs of every body (at most 40 000 drawn).
        if self.show_lattice {
            if let Some(ViewSource::Simulated(sim)) = &self.source {
                let stroke = egui::Stroke::new(
                    1.0,
                    egui::Color32::from_rgba_unmultiplied(120, 220, 140, 90),
                );
                let mut drawn = 0;
                for b in &sim.prepared.bodies {
                    let nodes = sim.prepared.world.body_positions(b.handle);
                    for s in &b.lattice.springs {
                        if drawn >= 40_000 {
                            break;
                        }
                        if let (Some(p), Some(q)) =
                            (to_pos(&nodes[s.a as usize]), to_pos(&nodes[s.b as usize]))
                        {
                            painter.line_segment([p, q], stroke);
                            drawn += 1;
                        }
                    }
                }
            }
        }
        // Contact overlay: a dot where a rigid surface pushed a body at the last substep.
        if self.show_contacts {
            if let Some(ViewSource::Simulated(sim)) = &self.source {
                let colour = egui::Color32::from_rgb(
                    raster::CONTACT_COLOUR[0],
                    raster::CONTACT_COLOUR[1],
                    raster::CONTACT_COLOUR[2],
                );
                for p in sim.prepared.world.touching_points() {
                    if let Some(at) = to_pos(&p) {
                        painter.circle_filled(at, 2.5, colour);
                    }
                }
            }
        }
        let mut status = format!("frame {}   ui {:.0} fps", self.frame, self.ui_fps);
        if let Some(live) = &self.live {
            if let Some(plan) = live.plan {
                status = format!(
                    "LIVE   ui {:.0} fps   {} steps/frame of {:.3} ms ({:.0} steps/s)   step {:.3} ms   draw {:.1} ms   {}   reaction {:.2} N",
                    self.ui_fps,
                    plan.steps,
                    plan.dt * 1e3,
                    live.steps_per_s,
                    self.timer.step_s.unwrap_or(0.0) * 1e3,
                    self.timer.draw_s.unwrap_or(0.0) * 1e3,
                    if plan.realtime { "real time".to_string() } else { format!("{:.2}× real time", plan.realtime_factor) },
                    live.reaction.norm()
                );
            }
        }
        painter.text(
            rect.left_top() + egui::vec2(8.0, 6.0),
            egui::Align2::LEFT_TOP,
            status,
            egui::FontId::monospace(12.0),
            egui::Color32::LIGHT_GRAY,
        );
        if let Some(e) = &self.error {
            painter.text(
                rect.left_bottom() + egui::vec2(8.0, -8.0),
                egui::Align2::LEFT_BOTTOM,
                e,
                egui::FontId::proportional(14.0),
                egui::Color32::from_rgb(255, 120, 110),
            );
        }
    }

    /// Mouse input on the 3-D view: camera, or the live capsule's gestures.
    fn handle_input(&mut self, ui: &egui::Ui, response: &egui::Response) -> Vec<Gesture> {
        let h = response.rect.height() as f64;
        let (scroll, zoom, shift) = ui.input(|i| {
            (
                i.smooth_scroll_delta().y as f64,
                i.zoom_delta() as f64,
                i.modifiers.shift,
            )
        });
        let hovered = response.hovered();
        let mut gestures = Vec::new();
        if zoom != 1.0 && hovered {
            self.camera.distance = (self.camera.distance / zoom).clamp(1e-3, 1e6);
        }
        match &self.live {
            None => {
                if response.dragged_by(egui::PointerButton::Primary)
                    || response.dragged_by(egui::PointerButton::Secondary)
                    || response.dragged_by(egui::PointerButton::Middle)
                {
                    let d = response.drag_delta();
                    self.camera.orbit(d.x as f64, d.y as f64);
                }
                if hovered && scroll != 0.0 {
                    self.camera.zoom(scroll / 50.0);
                }
            }
            Some(live) => {
                let m = &live.manipulator;
                let depth = self.camera.to_view(&m.centre).depth;
                let d = response.drag_delta();
                let (dx, dy) = (d.x as f64, d.y as f64);
                if response.dragged_by(egui::PointerButton::Primary) {
                    if shift {
                        gestures.push(Gesture::Move(self.camera.drag_vertical(dy, depth, h)));
                    } else {
                        gestures.push(Gesture::Move(self.camera.drag_horizontal(dx, dy, depth, h)));
                    }
                }
                if response.dragged_by(egui::PointerButton::Secondary) {
                    gestures.push(Gesture::Yaw(-0.5 * dx));
                }
                if response.dragged_by(egui::PointerButton::Middle) {
                    self.camera.orbit(dx, dy);
                }
                if hovered && scroll != 0.0 {
                    gestures.push(Gesture::Move(self.camera.up * (scroll * 0.002 * m.length)));
                }
            }
        }
        gestures
    }
}

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let now = Instant::now();
        let interval = now.duration_since(self.last_tick).as_secs_f64();
        self.last_tick = now;
        if interval > 0.0 {
            self.ui_fps = if self.ui_fps > 0.0 {
                0.9 * self.ui_fps + 0.1 / interval
            } else {
                1.0 / interval
            };
        }
        // Draw time of the previous frame: its CPU time less the stepping it did.
        if let Some(cpu) = frame.info().cpu_usage {
            let stepped = self.live.as_ref().map_or(0.0, |l| l.last_step_s);
            self.timer.record_draw((cpu as f64 - stepped).max(0.0));
        }
        if self.reloader.changed() {
            // The file is the truth again: its parameters replace the panel's.
            self.reopen(false);
        }
        if self.start_live && self.source.is_some() {
            self.start_live = false;
            self.toggle_live(true);
        }
        if self.playing && self.live.is_none() {
            if let Some(source) = &self.source {
                let fps = source.fps();
                let count = source.frame_count().max(1);
                self.frame_clock += interval;
                let mut next = self.frame;
                while self.frame_clock >= 1.0 / fps {
                    self.frame_clock -= 1.0 / fps;
                    next = if next >= count { 1 } else { next + 1 };
                }
                if next != self.frame {
                    self.seek(next);
                }
            }
        }
        egui::Panel::left("params")
            .default_size(300.0)
            .show(ui, |ui| self.side_panel(ui));
        egui::Panel::bottom("timeline").show(ui, |ui| self.bottom_panel(ui));
        egui::CentralPanel::default().show(ui, |ui| {
            let size = ui.available_size();
            let (response, painter) = ui.allocate_painter(size, egui::Sense::click_and_drag());
            let gestures = self.handle_input(ui, &response);
            let meshes = if self.live.is_some() {
                self.live_step(&gestures).unwrap_or_default()
            } else {
                self.recorded
                    .get(self.frame.saturating_sub(1))
                    .cloned()
                    .unwrap_or_default()
            };
            self.draw_view(&painter, response.rect, &meshes);
            let pixels_per_point = ui.ctx().pixels_per_point();
            self.write_trace(response.rect, pixels_per_point, &meshes);
        });
        if self.playing || self.live.is_some() {
            ui.ctx().request_repaint();
        }
    }
}
