//! CPU shading and the software rasterizer behind `springbake view --screenshot`: world-space
//! triangle meshes are projected with the [`OrbitCamera`], shaded flat with a Lambert key light
//! plus ambient (two-sided), and drawn with a z-buffer at 2× supersampling, then box-filtered
//! and written as an RGBA PNG. Fully deterministic and needs neither a GPU nor a display. The
//! window reuses [`shade`] and paints the triangles back to front with egui.

use crate::camera::{OrbitCamera, ScreenPoint};
use springbake_core::nalgebra::Vector3;
use springbake_core::particles::{OCTAHEDRON_CORNERS, OCTAHEDRON_FACES};
use springbake_core::solver::Capsule;

/// Background colour of screenshots and the 3-D view.
pub const BACKGROUND: [u8; 3] = [36, 40, 46];
/// Colour of the simulated bodies.
pub const BODY_COLOUR: [u8; 3] = [222, 120, 72];
/// Colour of manipulator capsules.
pub const CAPSULE_COLOUR: [u8; 3] = [110, 160, 230];
/// Colour of static colliders.
pub const COLLIDER_COLOUR: [u8; 3] = [150, 156, 168];

/// A triangle mesh in world metres with one colour.
#[derive(Debug, Clone, PartialEq)]
pub struct DrawMesh {
    pub positions: Vec<Vector3<f64>>,
    pub triangles: Vec<[u32; 3]>,
    pub colour: [u8; 3],
    /// An image over the surface through per-vertex UVs (drawn instead of `colour`).
    pub texture: Option<std::sync::Arc<TexturedSurface>>,
}

/// An 8-bit RGB image.
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<[u8; 3]>,
}

impl Texture {
    /// A PNG's or a JPEG's pixels, by the bytes' signature; `None` for anything else or an
    /// image that does not decode (the mesh keeps its colour).
    pub fn decode(bytes: &[u8]) -> Option<Texture> {
        if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
            Texture::from_jpeg(bytes)
        } else {
            Texture::from_png(bytes)
        }
    }

    /// A baseline or progressive JPEG's pixels as RGB (zune-jpeg; grey and CMYK converted).
    pub fn from_jpeg(bytes: &[u8]) -> Option<Texture> {
        use zune_jpeg::zune_core::{
            bytestream::ZCursor, colorspace::ColorSpace, options::DecoderOptions,
        };
        let options = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::RGB);
        let mut decoder = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(bytes), options);
        let pixels = decoder.decode().ok()?;
        let info = decoder.info()?;
        let (width, height) = (u32::from(info.width), u32::from(info.height));
        let count = width as usize * height as usize;
        (count > 0 && pixels.len() >= count * 3).then(|| Texture {
            width,
            height,
            rgb: pixels
                .chunks_exact(3)
                .take(count)
                .map(|p| [p[0], p[1], p[2]])
                .collect(),
        })
    }

    /// A PNG's pixels (8 or 16 bits, grey, RGB, palette, with or without alpha); `None` for
    /// anything else.
    pub fn from_png(bytes: &[u8]) -> Option<Texture> {
        let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
        let mut reader = decoder.read_info().ok()?;
        let mut buf = vec![0; reader.output_buffer_size()?];
        let info = reader.next_frame(&mut buf).ok()?;
        let channels = match info.color_type {
            png::ColorType::Grayscale => 1,
            png::ColorType::GrayscaleAlpha => 2,
            png::ColorType::Rgb => 3,
            png::ColorType::Rgba => 4,
            png::ColorType::Indexed => return None,
        };
        let (w, h) = (info.width as usize, info.height as usize);
        let rgb = (0..w * h)
            .map(|i| {
                let row = (i / w) * info.line_size;
                let p = &buf[row + (i % w) * channels..];
                if channels < 3 {
                    [p[0]; 3]
                } else {
                    [p[0], p[1], p[2]]
                }
            })
            .collect();
        (w > 0 && h > 0).then_some(Texture {
            width: info.width,
            height: info.height,
            rgb,
        })
    }

    /// The texel at `uv` (repeating, nearest; v = 0 is the image's top row, as in glTF).
    pub fn sample(&self, uv: [f64; 2]) -> [u8; 3] {
        let wrap = |t: f64, n: u32| {
            let f = t - t.floor();
            ((f * n as f64) as u32).min(n - 1)
        };
        let (x, y) = (wrap(uv[0], self.width), wrap(uv[1], self.height));
        self.rgb[(y * self.width + x) as usize]
    }
}

/// A texture and the UV of each vertex of the mesh it covers.
#[derive(Debug, Clone, PartialEq)]
pub struct TexturedSurface {
    pub texture: Texture,
    pub uvs: Vec<[f32; 2]>,
}

impl DrawMesh {
    /// Axis-aligned bounds of the vertices used by triangles, or `None` when there are none.
    pub fn bounds(&self) -> Option<(Vector3<f64>, Vector3<f64>)> {
        bounds_of(self.positions.iter())
    }
}

/// Axis-aligned bounds of points.
pub fn bounds_of<'a>(
    points: impl Iterator<Item = &'a Vector3<f64>>,
) -> Option<(Vector3<f64>, Vector3<f64>)> {
    points.fold(None, |acc, p| match acc {
        None => Some((*p, *p)),
        Some((lo, hi)) => Some((lo.inf(p), hi.sup(p))),
    })
}

/// A projected, shaded triangle.
#[derive(Debug, Clone, PartialEq)]
pub struct ShadedTriangle {
    pub points: [ScreenPoint; 3],
    /// Flat colour (a textured triangle: its texture at the centroid, shaded).
    pub colour: [u8; 3],
    /// A textured triangle: the surface, its corners' UVs and the light factor.
    pub texture: Option<(std::sync::Arc<TexturedSurface>, [[f32; 2]; 3], f64)>,
}

/// Lambert factor for a face normal seen from `to_eye`: ambient 0.25 plus 0.75 × the key
/// light (from the eye's upper left), both sides lit alike.
fn lambert(normal: &Vector3<f64>, to_eye: &Vector3<f64>, light: &Vector3<f64>) -> f64 {
    let n = if normal.dot(to_eye) < 0.0 {
        -normal
    } else {
        *normal
    };
    0.25 + 0.75 * n.dot(light).max(0.0)
}

/// Project and shade every triangle of `meshes` for a `width × height` viewport. Triangles with
/// a vertex behind the near plane, non-finite or zero-area ones are left out.
pub fn shade(
    meshes: &[DrawMesh],
    camera: &OrbitCamera,
    width: f64,
    height: f64,
) -> Vec<ShadedTriangle> {
    let proj = camera.projector(width, height);
    let light = (proj.up * 0.7 - proj.right * 0.35 - proj.forward * 0.6).normalize();
    let mut out = Vec::new();
    for mesh in meshes {
        let outward = closed_orientation(mesh);
        let screen: Vec<Option<ScreenPoint>> =
            mesh.positions.iter().map(|p| proj.project(p)).collect();
        for t in &mesh.triangles {
            let idx = t.map(|i| i as usize);
            if idx.iter().any(|&i| i >= mesh.positions.len()) {
                continue;
            }
            let (Some(a), Some(b), Some(c)) = (screen[idx[0]], screen[idx[1]], screen[idx[2]])
            else {
                continue;
            };
            let [pa, pb, pc] = idx.map(|i| mesh.positions[i]);
            let normal = (pb - pa).cross(&(pc - pa));
            let len = normal.norm();
            if !(len > 0.0 && len.is_finite()) {
                continue;
            }
            let centre = (pa + pb + pc) / 3.0;
            // A closed mesh's faces turned away from the eye are hidden by its front faces:
            // leave them out, so a painter's-order draw (the window) cannot show them.
            if outward != 0.0 && outward * normal.dot(&(proj.eye - centre)) < 0.0 {
                continue;
            }
            let k = lambert(&(normal / len), &(proj.eye - centre), &light);
            let texture = mesh.texture.as_ref().and_then(|surface| {
                let uv = idx.map(|i| surface.uvs.get(i).copied());
                match uv {
                    [Some(u0), Some(u1), Some(u2)] => Some((surface.clone(), [u0, u1, u2], k)),
                    _ => None,
                }
            });
            let base = match &texture {
                Some((surface, [u0, u1, u2], _)) => surface.texture.sample([
                    f64::from(u0[0] + u1[0] + u2[0]) / 3.0,
                    f64::from(u0[1] + u1[1] + u2[1]) / 3.0,
                ]),
                None => mesh.colour,
            };
            let colour = base.map(|c| (c as f64 * k).round().clamp(0.0, 255.0) as u8);
            out.push(ShadedTriangle {
                points: [a, b, c],
                colour,
                texture,
            });
        }
    }
    out
}

/// For a closed mesh (every edge, with coincident vertices welded, shared by exactly two
/// triangles): +1 when its winding points normals outwards (positive signed volume), −1 when
/// inwards; 0 for open meshes, whose both sides may show.
pub fn closed_orientation(mesh: &DrawMesh) -> f64 {
    use std::collections::HashMap;
    let mut weld: HashMap<[u64; 3], u32> = HashMap::with_capacity(mesh.positions.len());
    let ids: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
            let next = weld.len() as u32;
            *weld.entry(key).or_insert(next)
        })
        .collect();
    let mut edges: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.triangles.len() * 3);
    let mut volume = 0.0;
    for t in &mesh.triangles {
        let Some(w) = t
            .iter()
            .map(|&i| ids.get(i as usize).copied())
            .collect::<Option<Vec<u32>>>()
        else {
            return 0.0;
        };
        if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
            continue; // degenerate (a capsule's pole): no edge of a surface
        }
        for k in 0..3 {
            let (a, b) = (w[k], w[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        volume += a.dot(&b.cross(&c));
    }
    if edges.is_empty() || edges.values().any(|&n| n != 2) || volume == 0.0 || !volume.is_finite() {
        return 0.0;
    }
    volume.signum()
}

/// An 8-bit RGBA image, rows top to bottom.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
}

impl Image {
    pub fn filled(width: u32, height: u32, rgb: [u8; 3]) -> Image {
        let mut rgba = Vec::with_capacity(width as usize * height as usize * 4);
        for _ in 0..width as usize * height as usize {
            rgba.extend_from_slice(&[rgb[0], rgb[1], rgb[2], 255]);
        }
        Image {
            width,
            height,
            rgba,
        }
    }

    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = (y as usize * self.width as usize + x as usize) * 4;
        [
            self.rgba[i],
            self.rgba[i + 1],
            self.rgba[i + 2],
            self.rgba[i + 3],
        ]
    }

    /// Encode as a PNG file's bytes.
    pub fn to_png(&self) -> Result<Vec<u8>, png::EncodingError> {
        let mut bytes = Vec::new();
        {
            let mut encoder = png::Encoder::new(&mut bytes, self.width, self.height);
            encoder.set_color(png::ColorType::Rgba);
            encoder.set_depth(png::BitDepth::Eight);
            let mut writer = encoder.write_header()?;
            writer.write_image_data(&self.rgba)?;
        }
        Ok(bytes)
    }
}

/// Supersampling factor per axis.
const SSAA: u32 = 2;

/// Render `meshes` seen by `camera` into a `width × height` image on `BACKGROUND`.
pub fn render(meshes: &[DrawMesh], camera: &OrbitCamera, width: u32, height: u32) -> Image {
    render_layers(meshes, &[], camera, width, height)
}

/// [`render`], then `overlay` over it (in front of everything, hiding only itself).
pub fn render_layers(
    meshes: &[DrawMesh],
    overlay: &[DrawMesh],
    camera: &OrbitCamera,
    width: u32,
    height: u32,
) -> Image {
    let (w, h) = (width * SSAA, height * SSAA);
    let mut depth = vec![f64::INFINITY; w as usize * h as usize];
    let mut colour = vec![BACKGROUND; w as usize * h as usize];
    for layer in [meshes, overlay] {
        depth.fill(f64::INFINITY);
        for t in &shade(layer, camera, w as f64, h as f64) {
            fill_triangle(t, w, h, &mut depth, &mut colour);
        }
    }
    // Box filter down to the output size.
    let mut out = Image::filled(width, height, BACKGROUND);
    let n = SSAA * SSAA;
    for y in 0..height {
        for x in 0..width {
            let mut sum = [0u32; 3];
            for sy in 0..SSAA {
                for sx in 0..SSAA {
                    let c = colour[((y * SSAA + sy) * w + x * SSAA + sx) as usize];
                    for (s, &v) in sum.iter_mut().zip(&c) {
                        *s += v as u32;
                    }
                }
            }
            let i = ((y * width + x) * 4) as usize;
            for (o, s) in out.rgba[i..i + 3].iter_mut().zip(sum) {
                *o = ((s + n / 2) / n) as u8;
            }
        }
    }
    out
}

/// Scan-convert one triangle with a z-buffer: pixel centres inside the edge functions (top-left
/// rule not needed for opaque flat colours), depth interpolated as 1/z linear in screen space.
fn fill_triangle(t: &ShadedTriangle, w: u32, h: u32, depth: &mut [f64], colour: &mut [[u8; 3]]) {
    let [a, b, c] = t.points;
    let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if area.abs() < 1e-12 || !area.is_finite() {
        return;
    }
    let min_x = a.x.min(b.x).min(c.x).floor().max(0.0) as i64;
    let max_x = (a.x.max(b.x).max(c.x).ceil() as i64).min(w as i64 - 1);
    let min_y = a.y.min(b.y).min(c.y).floor().max(0.0) as i64;
    let max_y = (a.y.max(b.y).max(c.y).ceil() as i64).min(h as i64 - 1);
    if min_x > max_x || min_y > max_y {
        return;
    }
    let inv = [1.0 / a.depth, 1.0 / b.depth, 1.0 / c.depth];
    let edge = |p: &ScreenPoint, q: &ScreenPoint, x: f64, y: f64| {
        (q.x - p.x) * (y - p.y) - (q.y - p.y) * (x - p.x)
    };
    for y in min_y..=max_y {
        let py = y as f64 + 0.5;
        for x in min_x..=max_x {
            let px = x as f64 + 0.5;
            let w0 = edge(&b, &c, px, py) / area;
            let w1 = edge(&c, &a, px, py) / area;
            let w2 = edge(&a, &b, px, py) / area;
            if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                continue;
            }
            let z = 1.0 / (w0 * inv[0] + w1 * inv[1] + w2 * inv[2]);
            let i = (y as u32 * w + x as u32) as usize;
            if z < depth[i] {
                depth[i] = z;
                colour[i] = match &t.texture {
                    // Perspective-correct UV: interpolate uv / depth, then times depth.
                    Some((surface, uv, k)) => {
                        let at = |c: usize| {
                            z * (w0 * inv[0] * f64::from(uv[0][c])
                                + w1 * inv[1] * f64::from(uv[1][c])
                                + w2 * inv[2] * f64::from(uv[2][c]))
                        };
                        surface
                            .texture
                            .sample([at(0), at(1)])
                            .map(|v| (v as f64 * k).round().clamp(0.0, 255.0) as u8)
                    }
                    None => t.colour,
                };
            }
        }
    }
}

/// Colour of the floor and of its grid lines.
pub const FLOOR_COLOUR: [u8; 3] = [50, 55, 62];
pub const GRID_COLOUR: [u8; 3] = [78, 84, 94];

/// The grid spacing for a floor `size` metres across: 1, 2 or 5 × 10ⁿ m, about a tenth of it.
pub fn grid_spacing(size: f64) -> f64 {
    let rough = (size / 10.0).max(1e-6);
    let decade = 10f64.powf(rough.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|k| k * decade)
        .find(|&s| s >= rough)
        .unwrap_or(10.0 * decade)
}

/// The two horizontal unit axes of a floor under `up` (the first world axis not along up).
fn floor_axes(up: Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let trial = if up.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::z()
    };
    let a = (trial - up * up.dot(&trial)).normalize();
    (a, up.cross(&a))
}

/// The extent of box `lo..hi` along the floor axes: (a0, a1, b0, b1).
fn floor_extent(lo: Vector3<f64>, hi: Vector3<f64>, up: Vector3<f64>) -> [f64; 4] {
    let (a, b) = floor_axes(up);
    let mut e = [
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for i in 0..8 {
        let c = Vector3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        );
        e[0] = e[0].min(a.dot(&c));
        e[1] = e[1].max(a.dot(&c));
        e[2] = e[2].min(b.dot(&c));
        e[3] = e[3].max(b.dot(&c));
    }
    e
}

/// The grid spacing [`floor_meshes`] draws under `lo..hi`, metres.
pub fn floor_grid_spacing(lo: Vector3<f64>, hi: Vector3<f64>, up: Vector3<f64>) -> f64 {
    let [a0, a1, b0, b1] = floor_extent(lo, hi, up);
    grid_spacing((a1 - a0).max(b1 - b0).max(1e-3) * 1.5)
}

/// The floor at height `floor` along `up` under the box `lo..hi` (and a quarter of its size
/// around it): a quad and grid lines a hair above it every [`floor_grid_spacing`] metres, on
/// round coordinates, so the grid is a scale.
pub fn floor_meshes(
    lo: Vector3<f64>,
    hi: Vector3<f64>,
    up: Vector3<f64>,
    floor: f64,
) -> Vec<DrawMesh> {
    let (a, b) = floor_axes(up);
    let [a0, a1, b0, b1] = floor_extent(lo, hi, up);
    let size = (a1 - a0).max(b1 - b0).max(1e-3);
    let margin = 0.25 * size;
    let (a0, a1, b0, b1) = (a0 - margin, a1 + margin, b0 - margin, b1 + margin);
    let spacing = floor_grid_spacing(lo, hi, up);
    let at = |u: f64, v: f64, lift: f64| a * u + b * v + up * (floor + lift);
    let quad = |p: [Vector3<f64>; 4], mesh: &mut DrawMesh| {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend_from_slice(&p);
        mesh.triangles.push([base, base + 1, base + 2]);
        mesh.triangles.push([base, base + 2, base + 3]);
    };
    let mut plane = DrawMesh {
        texture: None,
        positions: Vec::new(),
        triangles: Vec::new(),
        colour: FLOOR_COLOUR,
    };
    quad(
        [
            at(a0, b0, 0.0),
            at(a1, b0, 0.0),
            at(a1, b1, 0.0),
            at(a0, b1, 0.0),
        ],
        &mut plane,
    );
    let mut grid = DrawMesh {
        texture: None,
        positions: Vec::new(),
        triangles: Vec::new(),
        colour: GRID_COLOUR,
    };
    let (w, lift) = (0.002 * size, 1e-4 * size);
    let lines = |from: f64, to: f64| {
        let first = (from / spacing).ceil() as i64;
        let last = (to / spacing).floor() as i64;
        (first..=last.min(first + 200)).map(move |k| k as f64 * spacing)
    };
    for u in lines(a0, a1) {
        quad(
            [
                at(u - w, b0, lift),
                at(u + w, b0, lift),
                at(u + w, b1, lift),
                at(u - w, b1, lift),
            ],
            &mut grid,
        );
    }
    for v in lines(b0, b1) {
        quad(
            [
                at(a0, v - w, lift),
                at(a1, v - w, lift),
                at(a1, v + w, lift),
                at(a0, v + w, lift),
            ],
            &mut grid,
        );
    }
    vec![plane, grid]
}

/// `mesh` with every triangle split in four until no edge is longer than `max_edge` (at most
/// `budget` triangles in all): the rasterizer drops a triangle with a corner behind the
/// camera, so a large collider drawn from close by needs small pieces.
pub fn subdivided(mesh: &DrawMesh, max_edge: f64, budget: usize) -> DrawMesh {
    let mut positions = mesh.positions.clone();
    let mut triangles = mesh.triangles.clone();
    let long = |p: &[Vector3<f64>], t: &[u32; 3]| {
        (0..3).any(|k| (p[t[k] as usize] - p[t[(k + 1) % 3] as usize]).norm() > max_edge)
    };
    while triangles.len() * 4 <= budget && triangles.iter().any(|t| long(&positions, t)) {
        let mut next = Vec::with_capacity(triangles.len() * 4);
        for t in &triangles {
            if !long(&positions, t) {
                next.push(*t);
                continue;
            }
            let mid = |a: u32, b: u32, p: &mut Vec<Vector3<f64>>| {
                p.push((p[a as usize] + p[b as usize]) * 0.5);
                (p.len() - 1) as u32
            };
            let [a, b, c] = *t;
            let ab = mid(a, b, &mut positions);
            let bc = mid(b, c, &mut positions);
            let ca = mid(c, a, &mut positions);
            next.extend_from_slice(&[[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        triangles = next;
    }
    DrawMesh {
        texture: None,
        positions,
        triangles,
        colour: mesh.colour,
    }
}

/// Soft contact shadows on the floor: under each mesh, three nested discs over its footprint
/// (its extent along the floor axes), darker towards the middle and fainter the higher the
/// mesh hangs above the floor.
pub fn shadow_meshes(meshes: &[DrawMesh], up: Vector3<f64>, floor: f64) -> Vec<DrawMesh> {
    let (a, b) = floor_axes(up);
    let mut out = Vec::new();
    for m in meshes {
        let Some((lo, hi)) = m.bounds() else {
            continue;
        };
        let [a0, a1, b0, b1] = floor_extent(lo, hi, up);
        let (ca, cb) = ((a0 + a1) * 0.5, (b0 + b1) * 0.5);
        let (ra, rb) = ((a1 - a0) * 0.5, (b1 - b0) * 0.5);
        let size = ra.max(rb).max(1e-6);
        let height = (m
            .positions
            .iter()
            .map(|p| up.dot(p))
            .fold(f64::INFINITY, f64::min)
            - floor)
            .max(0.0);
        let strength = 0.8 / (1.0 + 2.0 * height / size);
        for (k, (scale, dark)) in [(1.15, 0.35), (1.0, 0.65), (0.8, 1.0)]
            .into_iter()
            .enumerate()
        {
            let f = strength * dark;
            let colour = FLOOR_COLOUR.map(|c| (c as f64 * (1.0 - 0.7 * f)).round() as u8);
            let lift = (2.0 + k as f64) * 1e-4 * size;
            let mut disc = DrawMesh {
                texture: None,
                positions: vec![a * ca + b * cb + up * (floor + lift)],
                triangles: Vec::new(),
                colour,
            };
            let n = 32u32;
            for i in 0..n {
                let t = std::f64::consts::TAU * i as f64 / n as f64;
                let (s, c) = t.sin_cos();
                disc.positions.push(
                    a * (ca + ra * scale * c) + b * (cb + rb * scale * s) + up * (floor + lift),
                );
                disc.triangles.push([0, 1 + i, 1 + (i + 1) % n]);
            }
            out.push(disc);
        }
    }
    out
}

/// The room's side walls drawn as skirting boards: a low strip (a twelfth of the room's
/// width, at least 2 cm) along each side of the box `lo..hi` from `base` up along axis `up`,
/// both faces, in the colliders' colour (ground: no shadow), so the room shows without
/// hiding the bodies in it.
pub fn wall_meshes(lo: [f64; 3], hi: [f64; 3], up: usize, base: f64) -> DrawMesh {
    let (a, b) = match up {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let span = (hi[a] - lo[a]).max(hi[b] - lo[b]);
    let height = (span / 12.0).max(0.02);
    let corner = |u: f64, v: f64, h: f64| {
        let mut p = Vector3::zeros();
        p[a] = u;
        p[b] = v;
        p[up] = h;
        p
    };
    let ring = [
        (lo[a], lo[b]),
        (hi[a], lo[b]),
        (hi[a], hi[b]),
        (lo[a], hi[b]),
    ];
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for k in 0..4 {
        let (p, q) = (ring[k], ring[(k + 1) % 4]);
        let n = positions.len() as u32;
        positions.extend([
            corner(p.0, p.1, base),
            corner(q.0, q.1, base),
            corner(q.0, q.1, base + height),
            corner(p.0, p.1, base + height),
        ]);
        triangles.extend([
            [n, n + 1, n + 2],
            [n, n + 2, n + 3],
            [n, n + 2, n + 1],
            [n, n + 3, n + 2],
        ]);
    }
    DrawMesh {
        texture: None,
        positions,
        triangles,
        colour: COLLIDER_COLOUR,
    }
}

/// Colours of the overlays: lattice springs, contact points.
pub const LATTICE_COLOUR: [u8; 3] = [120, 220, 140];
pub const CONTACT_COLOUR: [u8; 3] = [255, 206, 60];

/// Segments as square rods `width` across, one mesh.
pub fn rods(segments: &[(Vector3<f64>, Vector3<f64>)], width: f64, colour: [u8; 3]) -> DrawMesh {
    let mut mesh = DrawMesh {
        positions: Vec::with_capacity(segments.len() * 8),
        triangles: Vec::with_capacity(segments.len() * 8),
        colour,
        texture: None,
    };
    let r = width * 0.5;
    for (p, q) in segments {
        let d = q - p;
        let Some(d) = d.try_normalize(1e-12) else {
            continue;
        };
        let helper = if d.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let u = d.cross(&helper).normalize() * r;
        let v = d.cross(&u);
        let first = mesh.positions.len() as u32;
        for end in [p, q] {
            mesh.positions.extend([end + u, end + v, end - u, end - v]);
        }
        for k in 0..4u32 {
            let (a, b) = (first + k, first + (k + 1) % 4);
            mesh.triangles.push([a, b, b + 4]);
            mesh.triangles.push([a, b + 4, a + 4]);
        }
    }
    mesh
}

/// Colour of particles.
pub const PARTICLE_COLOUR: [u8; 3] = [218, 218, 218];

/// Particles (centre, width in m) as one mesh of octahedra as wide as each
/// ([`springbake_core::particles::OCTAHEDRON_CORNERS`]).
pub fn particle_octahedra(particles: &[(Vector3<f64>, f64)]) -> DrawMesh {
    let mut mesh = DrawMesh {
        positions: Vec::with_capacity(particles.len() * 6),
        triangles: Vec::with_capacity(particles.len() * 8),
        colour: PARTICLE_COLOUR,
        texture: None,
    };
    for (centre, width) in particles {
        let first = mesh.positions.len() as u32;
        mesh.positions.extend(
            OCTAHEDRON_CORNERS
                .iter()
                .map(|c| centre + Vector3::from(c.map(f64::from)) * (width * 0.5)),
        );
        mesh.triangles
            .extend(OCTAHEDRON_FACES.iter().map(|t| t.map(|k| first + k)));
    }
    mesh
}

/// A closed triangle mesh of a capsule: `segments` around the axis, `rings` per hemispherical
/// cap (the cylinder is the band between the caps' equators).
pub fn capsule_mesh(capsule: &Capsule, segments: u32, rings: u32, colour: [u8; 3]) -> DrawMesh {
    let axis = capsule.axis.normalize();
    let u = capsule.fallback_normal();
    let v = axis.cross(&u);
    let (e0, e1) = capsule.endpoints();
    let r = capsule.radius;
    let segments = segments.max(3);
    let rings = rings.max(1);
    let mut positions = Vec::new();
    let half_pi = std::f64::consts::FRAC_PI_2;
    for (centre, from) in [(e0, -half_pi), (e1, 0.0)] {
        for k in 0..=rings {
            let phi = from + half_pi * k as f64 / rings as f64;
            for s in 0..segments {
                let theta = std::f64::consts::TAU * s as f64 / segments as f64;
                let radial = u * theta.cos() + v * theta.sin();
                let pole = (from < 0.0 && k == 0) || (from == 0.0 && k == rings);
                positions.push(if pole {
                    // Exactly one point, so the closed surface welds there.
                    centre + axis * (r * phi.signum())
                } else {
                    centre + axis * (r * phi.sin()) + radial * (r * phi.cos())
                });
            }
        }
    }
    let rows = 2 * (rings + 1);
    let mut triangles = Vec::new();
    for row in 0..rows - 1 {
        for s in 0..segments {
            let a = row * segments + s;
            let b = row * segments + (s + 1) % segments;
            let c = a + segments;
            let d = b + segments;
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    DrawMesh {
        texture: None,
        positions,
        triangles,
        colour,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(z: f64, colour: [u8; 3]) -> DrawMesh {
        DrawMesh {
            texture: None,
            positions: vec![
                Vector3::new(-0.5, -0.5, z),
                Vector3::new(0.5, -0.5, z),
                Vector3::new(0.5, 0.5, z),
                Vector3::new(-0.5, 0.5, z),
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            colour,
        }
    }

    fn front_camera() -> OrbitCamera {
        let mut cam = OrbitCamera::new(Vector3::zeros(), Vector3::y(), 3.0);
        // Eye on +Z looking down -Z.
        cam.yaw_deg = -90.0;
        cam.pitch_deg = 0.0;
        cam
    }

    #[test]
    fn a_facing_quad_covers_the_centre_and_leaves_the_corners_alone() {
        let cam = front_camera();
        assert!(
            (cam.eye() - Vector3::new(0.0, 0.0, 3.0)).norm() < 1e-9,
            "{:?}",
            cam.eye()
        );
        let img = render(&[quad(0.0, [200, 200, 200])], &cam, 64, 48);
        assert_eq!(img.rgba.len(), 64 * 48 * 4);
        let bg = [BACKGROUND[0], BACKGROUND[1], BACKGROUND[2], 255];
        for (x, y) in [(0, 0), (63, 0), (0, 47), (63, 47)] {
            assert_eq!(img.pixel(x, y), bg);
        }
        let centre = img.pixel(32, 24);
        assert_ne!(centre, bg);
        assert!(centre[0] > 100, "lit: {centre:?}");
        // Quad half-width 0.5 m at 3 m with fov 40°: 0.5 / 3 × focal(48) = 10.9 px.
        let focal = cam.focal_px(48.0);
        let half = 0.5 / 3.0 * focal;
        assert_eq!(img.pixel((32.0 + half - 1.5) as u32, 24), centre);
        assert_eq!(img.pixel((32.0 + half + 1.5) as u32, 24), bg);
    }

    #[test]
    fn the_nearer_surface_wins_whatever_the_draw_order() {
        let cam = front_camera();
        let near = quad(0.5, [250, 0, 0]);
        let far = quad(0.0, [0, 250, 0]);
        for order in [[near.clone(), far.clone()], [far, near]] {
            let img = render(&order, &cam, 32, 32);
            let c = img.pixel(16, 16);
            assert!(c[0] > 0 && c[1] == 0, "red in front: {c:?}");
        }
    }

    fn cube(flip: bool) -> DrawMesh {
        let (p, t) = springbake_core::shapes::box_mesh([0.0; 3], [1.0; 3]);
        let triangles = t
            .into_iter()
            .map(|[a, b, c]| if flip { [a, c, b] } else { [a, b, c] })
            .collect();
        DrawMesh {
            texture: None,
            positions: p.iter().map(|q| q.coords).collect(),
            triangles,
            colour: [200, 200, 200],
        }
    }

    #[test]
    fn closed_meshes_know_their_winding_and_lose_their_back_faces() {
        assert_eq!(closed_orientation(&cube(false)), 1.0);
        assert_eq!(closed_orientation(&cube(true)), -1.0);
        assert_eq!(closed_orientation(&quad(0.0, [1, 1, 1])), 0.0, "open");
        let cam = OrbitCamera::new(Vector3::new(0.5, 0.5, 0.5), Vector3::y(), 4.0);
        // Seen from a generic direction three faces (6 triangles) of a cube face the eye.
        for flip in [false, true] {
            assert_eq!(shade(&[cube(flip)], &cam, 100.0, 100.0).len(), 6);
        }
        // An open quad keeps both sides.
        assert_eq!(
            shade(&[quad(0.0, [1, 1, 1])], &front_camera(), 100.0, 100.0).len(),
            2
        );
        let mut back = front_camera();
        back.yaw_deg = 90.0;
        assert_eq!(shade(&[quad(0.0, [1, 1, 1])], &back, 100.0, 100.0).len(), 2);
        // A capsule (closed, poles welded) is closed too.
        let cap = Capsule {
            centre: Vector3::zeros(),
            axis: Vector3::x(),
            length: 1.0,
            radius: 0.2,
            velocity: Vector3::zeros(),
            friction: 0.0,
        };
        assert_ne!(
            closed_orientation(&capsule_mesh(&cap, 12, 4, CAPSULE_COLOUR)),
            0.0
        );
    }

    #[test]
    fn lambert_is_two_sided_and_brightest_facing_the_light() {
        let light = Vector3::new(0.0, 0.0, 1.0);
        let eye = Vector3::new(0.0, 0.0, 1.0);
        assert!((lambert(&Vector3::z(), &eye, &light) - 1.0).abs() < 1e-12);
        assert!((lambert(&-Vector3::z(), &eye, &light) - 1.0).abs() < 1e-12);
        assert!((lambert(&Vector3::x(), &eye, &light) - 0.25).abs() < 1e-12);
    }

    /// An 8×8 JPEG of one colour, (0.8, 0.15, 0.05) of full scale, as Blender 5.0.1 saves a
    /// new image's pixels (quality 90).
    const ORANGE_JPEG: &str = concat!(
        "/9j/4AAQSkZJRgABAQAAAQABAAD/4QAMTmVvR2VvAAAAWv/bAEMAAwICAwICAwMDAwQDAwQFCAUFBAQFCgcHBggM",
        "CgwMCwoLCw0OEhANDhEOCwsQFhARExQVFRUMDxcYFhQYEhQVFP/bAEMBAwQEBQQFCQUFCRQNCw0UFBQUFBQUFBQU",
        "FBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFP/AABEIAAgACAMBIgACEQEDEQH/xAAfAAAB",
        "BQEBAQEBAQAAAAAAAAAAAQIDBAUGBwgJCgv/xAC1EAACAQMDAgQDBQUEBAAAAX0BAgMABBEFEiExQQYTUWEHInEU",
        "MoGRoQgjQrHBFVLR8CQzYnKCCQoWFxgZGiUmJygpKjQ1Njc4OTpDREVGR0hJSlNUVVZXWFlaY2RlZmdoaWpzdHV2",
        "d3h5eoOEhYaHiImKkpOUlZaXmJmaoqOkpaanqKmqsrO0tba3uLm6wsPExcbHyMnK0tPU1dbX2Nna4eLj5OXm5+jp",
        "6vHy8/T19vf4+fr/xAAfAQADAQEBAQEBAQEBAAAAAAAAAQIDBAUGBwgJCgv/xAC1EQACAQIEBAMEBwUEBAABAncA",
        "AQIDEQQFITEGEkFRB2FxEyIygQgUQpGhscEJIzNS8BVictEKFiQ04SXxFxgZGiYnKCkqNTY3ODk6Q0RFRkdISUpT",
        "VFVWV1hZWmNkZWZnaGlqc3R1dnd4eXqCg4SFhoeIiYqSk5SVlpeYmZqio6Slpqeoqaqys7S1tre4ubrCw8TFxsfI",
        "ycrS09TV1tfY2dri4+Tl5ufo6ery8/T19vf4+fr/2gAMAwEAAhEDEQA/APDKKKK/Ej+4z//Z",
    );

    #[test]
    fn a_jpeg_texture_decodes_to_its_colour() {
        use base64::Engine as _;
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(ORANGE_JPEG)
            .unwrap();
        let t = Texture::decode(&bytes).unwrap();
        assert_eq!((t.width, t.height), (8, 8));
        // (204, 38, 13) to JPEG's rounding
        for texel in &t.rgb {
            let want = [204, 38, 13];
            for c in 0..3 {
                assert!((texel[c] as i32 - want[c]).abs() <= 8, "{texel:?}");
            }
        }
        assert!(
            Texture::decode(&bytes[..100]).is_none(),
            "a cut JPEG is refused"
        );
    }

    #[test]
    fn png_round_trips_size_and_pixels() {
        let mut img = Image::filled(5, 3, [1, 2, 3]);
        img.rgba[4..8].copy_from_slice(&[9, 8, 7, 255]);
        let bytes = img.to_png().unwrap();
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (5, 3));
        assert_eq!(&buf[..info.buffer_size()], &img.rgba[..]);
    }

    #[test]
    fn capsule_mesh_is_within_its_radius_of_the_axis() {
        let cap = Capsule {
            centre: Vector3::new(0.0, 1.0, 0.0),
            axis: Vector3::x(),
            length: 0.6,
            radius: 0.1,
            velocity: Vector3::zeros(),
            friction: 0.0,
        };
        let m = capsule_mesh(&cap, 12, 4, CAPSULE_COLOUR);
        for p in &m.positions {
            let d = (p - cap.closest_point(p)).norm();
            assert!((d - 0.1).abs() < 1e-9, "{p:?} at {d}");
        }
        let (lo, hi) = m.bounds().unwrap();
        assert!((lo.x + 0.4).abs() < 1e-9 && (hi.x - 0.4).abs() < 1e-9);
        assert_eq!(m.triangles.len(), 2 * 12 * (2 * 5 - 1));
    }
}
