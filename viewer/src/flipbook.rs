//! Flipbooks: a range of frames rendered offscreen (no GPU, no display) into an animated GIF,
//! or an MP4/WebM through the system's `ffmpeg` when it is installed, and a contact sheet of
//! one file's frames. Frames are rendered in order (a simulated scene steps through them) and
//! encoded 16 at a time, so memory does not grow with the length of the bake;
//! the GIF's colour quantisation, the slow part, runs on every core, and its result does not
//! depend on the thread count (each frame is quantised on its own).

use crate::raster::Image;
use crate::sheet::{contact_sheet, SheetRow};
use crate::source::ViewSource;
use crate::{initial_camera, render_frame, ViewerError, MAX_SCREENSHOT_SIDE};
use rayon::prelude::*;
use std::io::Write;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

/// What to render.
#[derive(Debug, Clone, PartialEq)]
pub struct FlipbookArgs {
    pub input: PathBuf,
    pub output: PathBuf,
    /// 1-based frames; `None`: all.
    pub frames: Option<RangeInclusive<usize>>,
    pub width: u32,
    pub height: u32,
    /// `(yaw, pitch)` in degrees instead of the default view.
    pub camera: Option<(f64, f64)>,
}

/// The output kinds a flipbook can be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Gif,
    Video,
}

fn kind(path: &Path) -> Result<Kind, ViewerError> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("gif") => Ok(Kind::Gif),
        Some("mp4" | "webm" | "mov" | "mkv") => Ok(Kind::Video),
        _ => Err(ViewerError::Usage(format!(
            "{}: a flipbook is a .gif, or an .mp4/.webm made with ffmpeg",
            path.display()
        ))),
    }
}

/// The frames `range` asks for in a file of `count` frames, checked.
pub fn frame_range(
    range: &Option<RangeInclusive<usize>>,
    count: usize,
    input: &Path,
) -> Result<RangeInclusive<usize>, ViewerError> {
    let r = range.clone().unwrap_or(1..=count.max(1));
    if *r.start() == 0 || r.start() > r.end() || *r.end() > count.max(1) {
        return Err(ViewerError::Usage(format!(
            "{}: frames {}..{} asked for; the file has frames 1..{count}",
            input.display(),
            r.start(),
            r.end()
        )));
    }
    Ok(r)
}

/// Frames rendered before they are encoded and dropped: memory stays bounded whatever the
/// length of the bake (a few frames per core at a time).
const FRAMES_PER_CHUNK: usize = 16;

/// Renders `args.frames` of `args.input` and writes the flipbook; returns the frame count.
/// Frames are rendered and encoded a chunk at a time, so a long bake takes no more memory
/// than a short one (besides the compressed output).
pub fn write_flipbook(args: &FlipbookArgs) -> Result<usize, ViewerError> {
    let kind = kind(&args.output)?;
    check_size(args.width, args.height)?;
    let registry = springbake_pipeline::default_registry();
    let mut source = ViewSource::open(&registry, &args.input)?;
    let range = frame_range(&args.frames, source.frame_count(), &args.input)?;
    let fps = source.fps();
    let camera = crate::aim(initial_camera(&source), args.camera);
    let io = |message| ViewerError::Io {
        path: args.output.clone(),
        message,
    };
    let mut sink = match kind {
        Kind::Gif => Sink::Gif(GifSink::new(args.width, args.height, fps).map_err(io)?),
        Kind::Video => Sink::Video(VideoSink::start(
            args.width,
            args.height,
            fps,
            &args.output,
        )?),
    };
    let frames: Vec<usize> = range.collect();
    for chunk in frames.chunks(FRAMES_PER_CHUNK) {
        let mut images = Vec::with_capacity(chunk.len());
        for &frame in chunk {
            let size = (args.width, args.height);
            images.push(render_frame(
                &mut source,
                &args.input,
                &camera,
                frame,
                size,
            )?);
        }
        match &mut sink {
            Sink::Gif(g) => g.push(&images).map_err(io)?,
            Sink::Video(v) => v.push(&images).map_err(io)?,
        }
    }
    let bytes = match sink {
        Sink::Gif(g) => g.finish().map_err(io)?,
        Sink::Video(v) => v.finish().map_err(io)?,
    };
    write(&args.output, &bytes)?;
    Ok(frames.len())
}

enum Sink {
    Gif(GifSink),
    Video(VideoSink),
}

/// An endlessly looping GIF being written (GIF delays are in hundredths of a second).
struct GifSink {
    encoder: gif::Encoder<Vec<u8>>,
    size: (u16, u16),
    delay: u16,
}

impl GifSink {
    fn new(width: u32, height: u32, fps: f64) -> Result<GifSink, String> {
        let size = (
            u16::try_from(width).map_err(|_| "wider than a GIF allows")?,
            u16::try_from(height).map_err(|_| "taller than a GIF allows")?,
        );
        let mut encoder =
            gif::Encoder::new(Vec::new(), size.0, size.1, &[]).map_err(|e| e.to_string())?;
        encoder
            .set_repeat(gif::Repeat::Infinite)
            .map_err(|e| e.to_string())?;
        Ok(GifSink {
            encoder,
            size,
            delay: (100.0 / fps.max(1.0)).round().clamp(2.0, 65_535.0) as u16,
        })
    }

    /// Quantises the images (NeuQuant, its fast setting, on every core) and appends them.
    fn push(&mut self, images: &[Image]) -> Result<(), String> {
        let (w, h) = self.size;
        let frames: Vec<gif::Frame<'static>> = images
            .par_iter()
            .map(|image| {
                let mut rgba = image.rgba.clone();
                let mut frame = gif::Frame::from_rgba_speed(w, h, &mut rgba, 10);
                frame.delay = self.delay;
                frame
            })
            .collect();
        for frame in &frames {
            self.encoder.write_frame(frame).map_err(|e| e.to_string())?;
        }
        Ok(())
    }

    fn finish(self) -> Result<Vec<u8>, String> {
        self.encoder.into_inner().map_err(|e| e.to_string())
    }
}

/// An endlessly looping GIF of `images` at `fps`.
pub fn gif_bytes(images: &[Image], fps: f64) -> Result<Vec<u8>, String> {
    let first = images.first().ok_or("no frames to write")?;
    let mut sink = GifSink::new(first.width, first.height, fps)?;
    sink.push(images)?;
    sink.finish()
}

/// A video being made by the system's `ffmpeg` (its default codec for the extension) from raw
/// frames on its standard input; read back as bytes at the end so the file is written
/// atomically like every output. No ffmpeg: a usage error that says so.
struct VideoSink {
    child: Child,
    file: PathBuf,
    _dir: tempfile::TempDir,
}

impl VideoSink {
    fn start(width: u32, height: u32, fps: f64, output: &Path) -> Result<VideoSink, ViewerError> {
        let io = |message: String| ViewerError::Io {
            path: output.to_path_buf(),
            message,
        };
        let dir = tempfile::tempdir().map_err(|e| io(e.to_string()))?;
        let ext = output.extension().and_then(|e| e.to_str()).unwrap_or("mp4");
        let file = dir.path().join(format!("flipbook.{ext}"));
        // Even sizes for yuv420p.
        let (w, h) = (width & !1, height & !1);
        let child = Command::new("ffmpeg")
            .args([
                "-loglevel",
                "error",
                "-y",
                "-f",
                "rawvideo",
                "-pix_fmt",
                "rgba",
            ])
            .args(["-s", &format!("{width}x{height}")])
            .args(["-r", &format!("{fps}"), "-i", "-"])
            .args(["-vf", &format!("crop={w}:{h}:0:0"), "-pix_fmt", "yuv420p"])
            .arg(&file)
            .stdin(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                ViewerError::Usage(format!(
                    "{}: an .{ext} flipbook needs ffmpeg on PATH ({e}); write a .gif instead, \
                     or install ffmpeg",
                    output.display()
                ))
            })?;
        Ok(VideoSink {
            child,
            file,
            _dir: dir,
        })
    }

    fn push(&mut self, images: &[Image]) -> Result<(), String> {
        let stdin = self.child.stdin.as_mut().ok_or("ffmpeg has no input")?;
        for image in images {
            stdin
                .write_all(&image.rgba)
                .map_err(|e| format!("ffmpeg stopped reading: {e}"))?;
        }
        Ok(())
    }

    fn finish(mut self) -> Result<Vec<u8>, String> {
        drop(self.child.stdin.take());
        let out = self.child.wait_with_output().map_err(|e| e.to_string())?;
        if !out.status.success() {
            return Err(format!(
                "ffmpeg failed: {}",
                String::from_utf8_lossy(&out.stderr).trim()
            ));
        }
        std::fs::read(&self.file).map_err(|e| e.to_string())
    }
}

/// A contact sheet of `count` frames of `input`, evenly spaced over `frames`.
pub fn write_sheet(
    input: &Path,
    output: &Path,
    frames: &Option<RangeInclusive<usize>>,
    count: usize,
    cell: (u32, u32),
) -> Result<(), ViewerError> {
    let registry = springbake_pipeline::default_registry();
    let source = ViewSource::open(&registry, input)?;
    let range = frame_range(frames, source.frame_count(), input)?;
    drop(source);
    let (a, b) = (*range.start(), *range.end());
    let count = count.clamp(1, b - a + 1);
    let picks: Vec<usize> = (0..count)
        .map(|k| {
            if count == 1 {
                a
            } else {
                a + (b - a) * k / (count - 1)
            }
        })
        .collect();
    let row = SheetRow {
        file: input.to_path_buf(),
        label: input
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
    };
    let image = contact_sheet(&[row], &picks, cell)?;
    let bytes = image.to_png().map_err(|e| ViewerError::Io {
        path: output.to_path_buf(),
        message: format!("cannot encode the PNG: {e}"),
    })?;
    write(output, &bytes)
}

fn check_size(width: u32, height: u32) -> Result<(), ViewerError> {
    if width == 0 || height == 0 || width > MAX_SCREENSHOT_SIDE || height > MAX_SCREENSHOT_SIDE {
        return Err(ViewerError::Usage(format!(
            "size {width}x{height} is out of range (1 to {MAX_SCREENSHOT_SIDE} pixels a side)"
        )));
    }
    Ok(())
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), ViewerError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| ViewerError::Io {
            path: dir.to_path_buf(),
            message: format!("cannot create the folder: {e}"),
        })?;
    }
    springbake_watcher::write_atomically(path, bytes).map_err(|e| ViewerError::Io {
        path: path.to_path_buf(),
        message: format!("cannot write it: {e}"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gif_holds_every_frame_at_the_frame_rate_and_loops() {
        let images: Vec<Image> = (0..5u8)
            .map(|k| Image::filled(16, 8, [k * 40, 255 - k * 40, 30]))
            .collect();
        let bytes = gif_bytes(&images, 24.0).unwrap();
        let mut options = gif::DecodeOptions::new();
        options.set_color_output(gif::ColorOutput::RGBA);
        let mut decoder = options.read_info(&bytes[..]).unwrap();
        let mut count = 0;
        while let Some(frame) = decoder.read_next_frame().unwrap() {
            assert_eq!(frame.delay, 4, "1/24 s is 4 hundredths");
            assert_eq!((frame.width, frame.height), (16, 8));
            let px = &frame.buffer[..4];
            let want = [count * 40, 255 - count * 40, 30];
            for c in 0..3 {
                assert!(
                    px[c].abs_diff(want[c]) <= 8,
                    "frame {count}: {px:?} vs {want:?}"
                );
            }
            count += 1;
        }
        assert_eq!(count, 5);
        assert_eq!(gif_bytes(&images, 24.0).unwrap(), bytes, "deterministic");
    }

    #[test]
    fn frame_ranges_are_checked_against_the_file() {
        let p = Path::new("x.glb");
        assert_eq!(frame_range(&None, 48, p).unwrap(), 1..=48);
        assert_eq!(frame_range(&Some(5..=9), 48, p).unwrap(), 5..=9);
        for (a, b) in [(0, 3), (5, 4), (40, 49)] {
            assert!(frame_range(&Some(a..=b), 48, p).is_err(), "{a}..{b}");
        }
        assert!(kind(Path::new("a.png")).is_err());
    }
}
