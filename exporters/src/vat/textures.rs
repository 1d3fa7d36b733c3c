//! Texel encodings of the vertex animation textures: float EXR (the Labs "HDR" textures, raw
//! values) and 8-bit PNG pairs (values normalised by bounds and split in two textures, as the
//! Labs shaders decode them: `t = pos + pos2 · 0.01`), and the per-vertex rotation whose `+Y`
//! is the normal.

use exr::prelude::{
    f16, Blocks, Compression, Encoding, Image, Layer, LayerAttributes, LineOrder, SpecificChannels,
    WritableImage,
};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use std::io::Cursor;

/// An RGBA float image, rows top to bottom.
pub struct Rgba {
    pub width: usize,
    pub height: usize,
    pub texels: Vec<[f32; 4]>,
}

/// Bits per channel of an EXR.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Depth {
    /// float32: positions (a metre-sized body keeps 0.1 µm).
    Full,
    /// float16: rotations (unit quaternions to 1e-3, half the bytes).
    Half,
}

/// The image as an RGBA EXR of `depth` (ZIP, increasing scan lines, written serially so the
/// same texels give the same bytes).
pub fn exr_bytes(image: &Rgba, depth: Depth) -> Result<Vec<u8>, String> {
    let width = image.width;
    let texel = |p: exr::math::Vec2<usize>| image.texels[p.y() * width + p.x()];
    let encoding = Encoding {
        compression: Compression::ZIP16,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let size = (image.width, image.height);
    let attributes = LayerAttributes::named("vat");
    let mut out = Cursor::new(Vec::new());
    let written = match depth {
        Depth::Full => {
            let pixels = |p| {
                let t = texel(p);
                (t[0], t[1], t[2], t[3])
            };
            let layer = Layer::new(size, attributes, encoding, SpecificChannels::rgba(pixels));
            Image::from_layer(layer)
                .write()
                .non_parallel()
                .to_buffered(&mut out)
        }
        Depth::Half => {
            let pixels = |p| {
                let t = texel(p).map(f16::from_f32);
                (t[0], t[1], t[2], t[3])
            };
            let layer = Layer::new(size, attributes, encoding, SpecificChannels::rgba(pixels));
            Image::from_layer(layer)
                .write()
                .non_parallel()
                .to_buffered(&mut out)
        }
    };
    written.map_err(|e| format!("EXR encoding: {e}"))?;
    Ok(out.into_inner())
}

/// The image as an 8-bit RGBA PNG; values already in `[0, 1]`.
pub fn png_bytes(width: usize, height: usize, rgba: &[[u8; 4]]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut out, width as u32, height as u32);
        encoder.set_color(png::ColorType::Rgba);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder
            .write_header()
            .map_err(|e| format!("PNG encoding: {e}"))?;
        let data: Vec<u8> = rgba.iter().flatten().copied().collect();
        writer
            .write_image_data(&data)
            .map_err(|e| format!("PNG encoding: {e}"))?;
    }
    Ok(out)
}

/// A value in `[0, 1]` split into the two 8-bit textures the Labs shaders add up as
/// `t = pos + pos2 · 0.01`: `pos` the largest 8-bit value not above `t`, `pos2` the rest
/// scaled by 100 (below 1/255 · 100, so it fits), which gives `t` to `1 / 51 000`.
pub fn split_ldr(t: f32) -> (u8, u8) {
    let t = t.clamp(0.0, 1.0) as f64;
    let high = (t * 255.0).floor().min(255.0);
    let rest = t - high / 255.0;
    let low = (rest * 100.0 * 255.0).round().min(255.0);
    (high as u8, low as u8)
}

/// What a shader reads back from [`split_ldr`]'s pair.
pub fn join_ldr(high: u8, low: u8) -> f32 {
    high as f32 / 255.0 + low as f32 / 255.0 * 0.01
}

/// The rotation taking `+Y` to `normal` and `+X` to a tangent perpendicular to it (`x, y, z,
/// w`), as the Labs rotation texture holds it; the tangent is the normal's cross product with
/// whichever of `X` or `Z` it is least aligned with, so it is defined everywhere.
pub fn normal_rotation(normal: [f32; 3]) -> [f32; 4] {
    let n = Vector3::new(normal[0] as f64, normal[1] as f64, normal[2] as f64);
    let n = if n.norm() > 0.0 {
        n.normalize()
    } else {
        Vector3::y()
    };
    let helper = if n.z.abs() < 0.9 {
        Vector3::z()
    } else {
        Vector3::x()
    };
    let tangent = helper.cross(&n).normalize();
    let bitangent = tangent.cross(&n);
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[tangent, n, bitangent]));
    let q = UnitQuaternion::from_rotation_matrix(&r);
    let q = if q.w < 0.0 {
        -q.into_inner()
    } else {
        q.into_inner()
    };
    [q.i as f32, q.j as f32, q.k as f32, q.w as f32]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_values_come_back_to_the_shaders_precision() {
        for k in 0..=1000 {
            let t = k as f32 / 1000.0;
            let (h, l) = split_ldr(t);
            let back = join_ldr(h, l);
            assert!((back - t).abs() < 1.0 / 50_000.0, "{t}: {back}");
        }
    }

    #[test]
    fn the_rotation_takes_up_to_the_normal() {
        for n in [
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.3, -0.8, 0.2],
            [0.0, -1.0, 0.0],
        ] {
            let q = normal_rotation(n);
            let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                q[3] as f64,
                q[0] as f64,
                q[1] as f64,
                q[2] as f64,
            ));
            let up = q * Vector3::y();
            let want = Vector3::new(n[0] as f64, n[1] as f64, n[2] as f64).normalize();
            assert!((up - want).norm() < 1e-6, "{n:?} → {up}");
        }
    }

    #[test]
    fn exr_of_the_same_texels_is_the_same_bytes() {
        let image = Rgba {
            width: 3,
            height: 2,
            texels: (0..6).map(|i| [i as f32, 0.5, -1.0, 1.0]).collect(),
        };
        let a = exr_bytes(&image, Depth::Full).unwrap();
        assert_eq!(a, exr_bytes(&image, Depth::Full).unwrap());
        assert!(exr_bytes(&image, Depth::Half).unwrap().len() < a.len());
        assert!(a.starts_with(&[0x76, 0x2f, 0x31, 0x01]), "EXR magic");
    }
}
