//! springbake's viewer: `springbake view FILE` opens an egui window (orbit camera, shaded mesh,
//! lattice overlay, play/pause/scrub, live mode with a mouse-driven capsule, a parameter panel
//! with a spring plot, live reload); `springbake view FILE --screenshot OUT.png` renders one
//! frame with the software rasterizer and exits, needing neither a GPU nor a display.
//!
//! Modules: [`camera`] (orbit camera math), [`raster`] (CPU shading, z-buffer rasterizer, PNG),
//! [`source`] (what a file opens as: simulated scene/mesh or baked glTF playback), [`live`]
//! (manipulator drag with resistance, real-time step plan), [`oscillator`] (the spring plot),
//! [`reload`] (watcher thread), [`sheet`] (contact sheets of several bakes), [`flipbook`]
//! (animated GIF/MP4 and one file's contact sheet), [`report_page`] (the HTML bake report),
//! and the window itself (private `app`).

mod app;
pub mod camera;
pub mod flipbook;
pub mod live;
pub mod oscillator;
pub mod raster;
pub mod reload;
pub mod report_page;
pub mod sheet;
pub mod source;

use camera::OrbitCamera;
use source::ViewSource;
use springbake_core::plugin::PluginError;
use springbake_core::solver::SimulationError;
use springbake_pipeline::PipelineError;
use std::path::PathBuf;

/// Why the viewer could not show a file. `is_user_error` tells the CLI to exit with code 2.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    #[error("{0}")]
    Pipeline(#[from] PipelineError),
    #[error("{0}")]
    Plugin(#[from] PluginError),
    #[error("{0}")]
    Simulation(#[from] SimulationError),
    #[error("{path}: {message}")]
    Io { path: PathBuf, message: String },
    #[error("{0}")]
    Usage(String),
    /// The window could not open (no display, no OpenGL).
    #[error("cannot open the viewer window: {0}; `springbake view FILE --screenshot OUT.png` renders without a display")]
    Window(String),
}

impl ViewerError {
    /// True when the user's input is at fault (exit code 2).
    pub fn is_user_error(&self) -> bool {
        match self {
            ViewerError::Pipeline(p) => p.is_user_error(),
            ViewerError::Plugin(_) | ViewerError::Usage(_) => true,
            ViewerError::Simulation(s) => matches!(s, SimulationError::NonFinite { .. }),
            ViewerError::Io { .. } | ViewerError::Window(_) => false,
        }
    }
}

/// `springbake view FILE`: what the window opens.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewArgs {
    /// A scene (.toml), a mesh, or a baked .glb/.gltf.
    pub input: PathBuf,
    /// 1-based frame to start at.
    pub frame: usize,
    /// Open in live mode (a scene or mesh: the mouse drives a capsule).
    pub live: bool,
    /// Append one JSON line per drawn frame here (time, frame rate, live mode, the bodies'
    /// top along up, the live capsule's centre, the 3-D view's centre in window pixels): for
    /// tests and bug reports.
    pub trace: Option<PathBuf>,
}

/// `springbake view FILE --screenshot OUT.png [--frame N]`.
#[derive(Debug, Clone, PartialEq)]
pub struct ScreenshotArgs {
    /// A scene (.toml), a mesh, or a baked .glb/.gltf.
    pub input: PathBuf,
    /// 1-based frame (1 = the initial state); a simulation is stepped to it.
    pub frame: usize,
    /// The PNG to write.
    pub output: PathBuf,
    pub width: u32,
    pub height: u32,
    /// Frame the whole motion (the camera every frame of a flipbook uses) instead of the
    /// bodies at `frame`.
    pub frame_all: bool,
    /// `(yaw, pitch)` of the view in degrees instead of the default three-quarter view.
    pub camera: Option<(f64, f64)>,
    /// What is drawn over the picture.
    pub overlays: Overlays,
}

/// What a screenshot draws over the scene, in front of everything (a simulated scene's; a
/// baked file has no lattice or contacts to show).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Overlays {
    /// Every body's lattice springs (at most [`MAX_OVERLAY_SPRINGS`]).
    pub lattice: bool,
    /// The display-surface points a floor, wall, capsule or collider pushes at the frame.
    pub contacts: bool,
}

/// Width of an overlay's lines, over the camera's distance.
const OVERLAY_WIDTH: f64 = 0.002;

/// Most lattice springs an overlay draws.
pub const MAX_OVERLAY_SPRINGS: usize = 40_000;

impl ScreenshotArgs {
    /// Frame 1 at 800 × 600, framing the bodies at the frame.
    pub fn new(input: impl Into<PathBuf>, output: impl Into<PathBuf>) -> ScreenshotArgs {
        ScreenshotArgs {
            input: input.into(),
            frame: 1,
            output: output.into(),
            width: 800,
            height: 600,
            frame_all: false,
            camera: None,
            overlays: Overlays::default(),
        }
    }
}

/// Turns `camera` to `angles` (yaw, pitch in degrees) when given.
pub fn aim(mut camera: OrbitCamera, angles: Option<(f64, f64)>) -> OrbitCamera {
    if let Some((yaw, pitch)) = angles {
        camera.yaw_deg = yaw;
        camera.pitch_deg = pitch.clamp(-89.0, 89.0);
    }
    camera
}

/// Largest screenshot side, pixels.
pub const MAX_SCREENSHOT_SIDE: u32 = 8192;

/// The camera a file opens with: framing [`ViewSource::view_bounds`], taken before any step so
/// every frame of one file is drawn from the same view.
pub fn initial_camera(source: &ViewSource) -> OrbitCamera {
    let (lo, hi) = source.view_bounds().unwrap_or_default();
    OrbitCamera::framing(lo, hi, source.up())
}

/// The camera a screenshot of 1-based `frame` uses: the bodies there and the floor under them,
/// from the same three-quarter view as [`initial_camera`].
pub fn camera_at(source: &mut ViewSource, frame: usize) -> Result<OrbitCamera, ViewerError> {
    let (lo, hi) = source
        .bounds_at(frame.min(source.frame_count().max(1)))?
        .unwrap_or_default();
    Ok(OrbitCamera::framing(lo, hi, source.up()))
}

/// Render frame `args.frame` of `args.input` to a PNG with the software rasterizer, the camera
/// framing the bodies at that frame and the floor under them ([`camera_at`]), or the whole
/// motion ([`initial_camera`]) with `frame_all`.
pub fn render_screenshot(args: &ScreenshotArgs) -> Result<(), ViewerError> {
    if args.width == 0
        || args.height == 0
        || args.width > MAX_SCREENSHOT_SIDE
        || args.height > MAX_SCREENSHOT_SIDE
    {
        return Err(ViewerError::Usage(format!(
            "screenshot size {}x{} is out of range (1 to {MAX_SCREENSHOT_SIDE} pixels a side)",
            args.width, args.height
        )));
    }
    if args.frame == 0 {
        return Err(ViewerError::Usage("frames are numbered from 1".into()));
    }
    let registry = springbake_pipeline::default_registry();
    let mut source = ViewSource::open(&registry, &args.input)?;
    let camera = if args.frame_all {
        initial_camera(&source)
    } else {
        camera_at(&mut source, args.frame)?
    };
    let camera = aim(camera, args.camera);
    let size = (args.width, args.height);
    let image = render_frame_with(
        &mut source,
        &args.input,
        &camera,
        args.frame,
        size,
        args.overlays,
    )?;
    let bytes = image.to_png().map_err(|e| ViewerError::Io {
        path: args.output.clone(),
        message: format!("cannot encode the PNG: {e}"),
    })?;
    if let Some(dir) = args.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| ViewerError::Io {
            path: dir.to_path_buf(),
            message: format!("cannot create the folder: {e}"),
        })?;
    }
    springbake_watcher::write_atomically(&args.output, &bytes).map_err(|e| ViewerError::Io {
        path: args.output.clone(),
        message: format!("cannot write the screenshot: {e}"),
    })?;
    Ok(())
}

/// Frame `frame` (1-based) of `source` (opened from `input`) seen by `camera`, with its floor,
/// `width × height` pixels.
pub fn render_frame(
    source: &mut ViewSource,
    input: &std::path::Path,
    camera: &OrbitCamera,
    frame: usize,
    size: (u32, u32),
) -> Result<raster::Image, ViewerError> {
    render_frame_with(source, input, camera, frame, size, Overlays::default())
}

/// [`render_frame`] with `overlays` drawn over it.
pub fn render_frame_with(
    source: &mut ViewSource,
    input: &std::path::Path,
    camera: &OrbitCamera,
    frame: usize,
    (width, height): (u32, u32),
    overlays: Overlays,
) -> Result<raster::Image, ViewerError> {
    if frame > source.frame_count() && matches!(source, ViewSource::Baked(_)) {
        return Err(ViewerError::Usage(format!(
            "{}: frame {} asked for, the file has {} frames",
            input.display(),
            frame,
            source.frame_count()
        )));
    }
    let up = source.up();
    let mut meshes = source.meshes_at(frame)?;
    // Colliders in pieces no longer than a tenth of what the camera frames (module docs of
    // `raster::subdivided`).
    let reach = 0.1 * camera.distance.max(1e-3);
    for m in meshes
        .iter_mut()
        .filter(|m| m.colour == raster::COLLIDER_COLOUR)
    {
        *m = raster::subdivided(m, reach, 200_000);
    }
    let mut hud = format!("frame {frame}  {:.2} s", (frame - 1) as f64 / source.fps());
    if let (Some(h), Some((lo, hi))) = (source.floor(), source.view_bounds()) {
        // Bodies and capsules cast shadows; colliders are part of the ground.
        let casters: Vec<raster::DrawMesh> = meshes
            .iter()
            .filter(|m| m.colour != raster::COLLIDER_COLOUR)
            .cloned()
            .collect();
        let shadows = raster::shadow_meshes(&casters, up, h);
        meshes.extend(raster::floor_meshes(lo, hi, up, h));
        meshes.extend(shadows);
        hud += &format!("  grid {}", metres(raster::floor_grid_spacing(lo, hi, up)));
    }
    let over = source.overlay_meshes(overlays, OVERLAY_WIDTH * camera.distance);
    let mut image = raster::render_layers(&meshes, &over, camera, width, height);
    // Twice the font's size where it fits, else its own 8 pixels.
    let scale = if 12 + 16 * hud.chars().count() as u32 <= width {
        2
    } else {
        1
    };
    if height >= 40 {
        let y = height - 10 * scale - 2;
        sheet::draw_text(&mut image, 6, y, &hud, [200, 205, 215], width - 6, scale);
    }
    Ok(image)
}

/// A length for the HUD: `0.1 m`, `2 cm`, `5 mm`, `20 m`.
fn metres(m: f64) -> String {
    if m >= 1.0 {
        format!("{m} m")
    } else if m >= 0.01 {
        format!("{} cm", (m * 100.0 * 1000.0).round() / 1000.0)
    } else {
        format!("{} mm", (m * 1000.0 * 1000.0).round() / 1000.0)
    }
}

/// Open the interactive window on `args.input` and return when it is closed.
pub fn run_viewer(args: ViewArgs) -> Result<(), ViewerError> {
    app::run(args)
}
