//! `springbake view`: the interactive window, or offscreen pictures of a file (a screenshot,
//! a flipbook, a contact sheet) through the viewer crate's software rasterizer.

use crate::Failure;
use springbake_viewer::{flipbook, ViewerError};
use std::path::PathBuf;

/// `springbake view`'s arguments.
#[derive(clap::Args)]
pub struct ViewCommand {
    /// A scene file (.toml), a mesh, or a baked .glb/.gltf (morph frames are played back).
    pub file: PathBuf,
    /// Render this frame with the software rasterizer to a PNG and exit (no window, no GPU).
    #[arg(long, value_name = "OUT.png")]
    pub screenshot: Option<PathBuf>,
    /// Render the frames (all, or --frames) offscreen to an animated GIF, or to an
    /// MP4/WebM through ffmpeg when it is installed, and exit.
    #[arg(long, value_name = "OUT.gif")]
    pub flipbook: Option<PathBuf>,
    /// Render a contact sheet PNG of --count frames spread over the file (or --frames).
    #[arg(long, value_name = "OUT.png")]
    pub sheet: Option<PathBuf>,
    /// Frames for --flipbook and --sheet: A..B (1-based, inclusive).
    #[arg(long, value_name = "A..B", value_parser = parse_frames)]
    pub frames: Option<std::ops::RangeInclusive<usize>>,
    /// Frames on a --sheet.
    #[arg(long, default_value_t = 6, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub count: u32,
    /// Frame to show (1 = the initial state).
    #[arg(long, default_value_t = 1)]
    pub frame: usize,
    /// A --screenshot frames the whole motion (as a flipbook does), not the bodies at
    /// --frame.
    #[arg(long)]
    pub frame_all: bool,
    /// The view of --screenshot and --flipbook as YAW,PITCH in degrees (default
    /// -60,20: from the front right, a little above).
    #[arg(long, value_name = "YAW,PITCH", value_parser = parse_angles, allow_hyphen_values = true)]
    pub camera: Option<(f64, f64)>,
    /// Open the window in live mode (a scene or mesh: the mouse drives a capsule; drag to
    /// move it, shift-drag up and down, right-drag to turn it).
    #[arg(long)]
    pub live: bool,
    /// Append one JSON line per drawn frame of the window to this file (frame rate, live
    /// mode, the bodies' top, the view's centre): for tests and bug reports.
    #[arg(long, value_name = "FILE.jsonl")]
    pub trace: Option<PathBuf>,
    /// Draw over a --screenshot of a scene: `lattice` (every body's springs), `contacts`
    /// (the surface points the floor, walls, capsules and colliders push), or both,
    /// comma-separated. A baked file has neither.
    #[arg(long, value_name = "lattice,contacts", value_delimiter = ',')]
    pub overlay: Vec<Overlay>,
    /// Image size in pixels, WIDTHxHEIGHT (default 800x600; 480x360 for a flipbook, 320x240
    /// per frame of a sheet).
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
}

/// `YAW,PITCH` (degrees) for `view --camera`.
fn parse_angles(s: &str) -> Result<(f64, f64), String> {
    let (y, p) = s
        .split_once(',')
        .ok_or_else(|| format!("expected YAW,PITCH in degrees, got \"{s}\""))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("\"{v}\" is not a number of degrees"))
    };
    Ok((parse(y)?, parse(p)?))
}

/// `A..B` or `A` for `view --frames`.
fn parse_frames(s: &str) -> Result<std::ops::RangeInclusive<usize>, String> {
    let parse = |v: &str| {
        v.trim()
            .parse::<usize>()
            .map_err(|e| format!("\"{v}\": {e} (write A..B, e.g. 1..48)"))
    };
    match s.split_once("..") {
        Some((a, b)) => Ok(parse(a)?..=parse(b.trim_start_matches('='))?),
        None => {
            let a = parse(s)?;
            Ok(a..=a)
        }
    }
}

/// `WIDTHxHEIGHT` for `view --size`.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WIDTHxHEIGHT, got \"{s}\""))?;
    let parse = |v: &str| v.trim().parse::<u32>().map_err(|e| format!("\"{v}\": {e}"));
    Ok((parse(w)?, parse(h)?))
}

pub fn run(args: ViewCommand) -> Result<(), Failure> {
    let failure = |e: ViewerError| Failure {
        code: if e.is_user_error() { 2 } else { 1 },
        message: e.to_string(),
    };
    if let Some(output) = &args.flipbook {
        let (width, height) = args.size.unwrap_or((480, 360));
        let started = std::time::Instant::now();
        let n = flipbook::write_flipbook(&flipbook::FlipbookArgs {
            input: args.file.clone(),
            output: output.clone(),
            frames: args.frames.clone(),
            width,
            height,
            camera: args.camera,
        })
        .map_err(failure)?;
        println!(
            "flipbook of {n} frames in {:.1} s: {}",
            started.elapsed().as_secs_f64(),
            output.display()
        );
    }
    if let Some(output) = &args.sheet {
        let cell = args.size.unwrap_or((320, 240));
        flipbook::write_sheet(&args.file, output, &args.frames, args.count as usize, cell)
            .map_err(failure)?;
        println!("contact sheet: {}", output.display());
    }
    let pictures = args.flipbook.is_some() || args.sheet.is_some();
    match &args.screenshot {
        Some(output) => shoot(&args, output.clone()),
        None if pictures => Ok(()),
        None => springbake_viewer::run_viewer(springbake_viewer::ViewArgs {
            input: args.file.clone(),
            frame: args.frame,
            live: args.live,
            trace: args.trace.clone(),
        }),
    }
    .map_err(failure)
}

fn shoot(args: &ViewCommand, output: PathBuf) -> Result<(), ViewerError> {
    let (width, height) = args.size.unwrap_or((800, 600));
    springbake_viewer::render_screenshot(&springbake_viewer::ScreenshotArgs {
        input: args.file.clone(),
        frame: args.frame,
        output,
        width,
        height,
        frame_all: args.frame_all,
        camera: args.camera,
        overlays: springbake_viewer::Overlays {
            lattice: args.overlay.contains(&Overlay::Lattice),
            contacts: args.overlay.contains(&Overlay::Contacts),
        },
    })
}

/// What `view --overlay` draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Overlay {
    Lattice,
    Contacts,
}
