//! Built-in triangle meshes (a box, a UV sphere) for the demo, tests and benchmarks.

use nalgebra::Point3;

/// An axis-aligned box from `lo` to `hi`: 8 corners, 12 outward-facing triangles.
pub fn box_mesh(lo: [f64; 3], hi: [f64; 3]) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    let p = |i: u32| {
        Point3::new(
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        )
    };
    let positions = (0..8).map(p).collect();
    let triangles = vec![
        [0, 2, 1],
        [1, 2, 3], // z = lo
        [4, 5, 6],
        [5, 7, 6], // z = hi
        [0, 1, 4],
        [1, 5, 4], // y = lo
        [2, 6, 3],
        [3, 6, 7], // y = hi
        [0, 4, 2],
        [2, 4, 6], // x = lo
        [1, 3, 5],
        [3, 7, 5], // x = hi
    ];
    (positions, triangles)
}

/// A UV sphere of `radius` around `centre` with `rings` × `segments` quads (split in two).
pub fn uv_sphere(
    centre: [f64; 3],
    radius: f64,
    rings: u32,
    segments: u32,
) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    let mut positions = vec![Point3::new(centre[0], centre[1] + radius, centre[2])];
    for r in 1..rings {
        let phi = std::f64::consts::PI * r as f64 / rings as f64;
        for s in 0..segments {
            let theta = 2.0 * std::f64::consts::PI * s as f64 / segments as f64;
            positions.push(Point3::new(
                centre[0] + radius * phi.sin() * theta.cos(),
                centre[1] + radius * phi.cos(),
                centre[2] - radius * phi.sin() * theta.sin(),
            ));
        }
    }
    positions.push(Point3::new(centre[0], centre[1] - radius, centre[2]));
    let bottom = positions.len() as u32 - 1;
    let ring = |r: u32, s: u32| 1 + (r - 1) * segments + (s % segments);
    let mut triangles = Vec::new();
    for s in 0..segments {
        triangles.push([0, ring(1, s), ring(1, s + 1)]);
        triangles.push([bottom, ring(rings - 1, s + 1), ring(rings - 1, s)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (
                ring(r, s),
                ring(r, s + 1),
                ring(r + 1, s),
                ring(r + 1, s + 1),
            );
            triangles.push([a, c, b]);
            triangles.push([b, c, d]);
        }
    }
    (positions, triangles)
}
