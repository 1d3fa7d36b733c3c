//! The step loop allocates nothing (issue 9): once a world's buffers have grown, `World::step`
//! and `World::advance_frame` make no heap allocation, through free fall, an impact that needs
//! the fusion model's later sweeps, resting contact and a capsule pressed into the body.
//! Counted with a global allocator that forwards to the system's and counts calls.
#![allow(clippy::unwrap_used)]
// The counting allocator is the one unsafe item: a forwarding `GlobalAlloc`.
#![allow(unsafe_code)]

mod support;

use springbake_core::lattice::surface_samples;
use springbake_core::material::Material;
use springbake_core::nalgebra::Vector3;
use springbake_core::solver::{BodyHandle, Capsule, Integrator, RigidBody, World};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use support::{fitted_box, floor_settings};

struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

// SAFETY: every call forwards to `System` with the caller's arguments unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The counter is process-wide: the tests of this file take turns.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Heap allocations made by `f` (on any thread).
fn allocations_in(f: impl FnOnce()) -> u64 {
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    COUNTING.store(true, Ordering::Relaxed);
    f();
    COUNTING.store(false, Ordering::Relaxed);
    ALLOCATIONS.load(Ordering::Relaxed) - before
}

/// A soft 0.3 m cube thrown down at 6 m/s from `drop_m` above the floor, with its display
/// surface taking the contacts (the product's set-up).
fn dropped_cube(drop_m: f64) -> World {
    let (p, t, lattice) = fitted_box([0.0, drop_m, 0.0], [0.3, drop_m + 0.3, 0.3], 6);
    let m = Material::preset("jelly").unwrap();
    let mut w = World::new(floor_settings(&lattice, &m, 0.4));
    let body = w.add_lattice_body("cube", &lattice, &m, Vector3::new(0.0, -6.0, 0.0));
    let (samples, areas) = surface_samples(&p, &t, 0.5 * lattice.cell_size);
    w.add_contact_surface(body, &lattice, &samples, &areas);
    w
}

/// Frames 1–6 of the dropped cube: the first frames grow every buffer (prepared arrays,
/// dispersion scratch, contact log) through the same kinds of events as the counted frames,
/// the impact included.
fn warm_up_through_the_impact(w: &mut World) {
    let mut corrections = 0;
    for f in 1..=6 {
        corrections += w
            .advance_frame(1.0 / 24.0, f, &|| false)
            .unwrap()
            .dispersion_corrections;
    }
    assert!(corrections > 0, "the impact must need the fusion model");
}

#[test]
fn steps_allocate_nothing_once_the_buffers_have_grown() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    pool.install(|| {
        let mut w = dropped_cube(0.05);
        warm_up_through_the_impact(&mut w);
        // Counted: the body bounces and comes to rest on its contact surface.
        let mut counted_depth = 0.0f64;
        let n = allocations_in(|| {
            for f in 7..=18 {
                let d = w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
                counted_depth = counted_depth.max(d.max_penetration);
            }
        });
        assert!(
            counted_depth > 0.0,
            "the counted frames must touch the floor"
        );
        assert_eq!(n, 0, "{n} heap allocations in 12 frames of stepping");

        // A capsule pressed into the resting body (the viewer's live mode).
        w.live_capsules.push(Capsule {
            centre: Vector3::new(0.15, 0.32, 0.15),
            axis: Vector3::x(),
            length: 0.4,
            radius: 0.05,
            velocity: Vector3::zeros(),
            friction: 0.3,
        });
        let dt = w.choose_substeps(1.0 / 24.0).dt;
        for _ in 0..50 {
            w.step(dt);
        }
        let n = allocations_in(|| {
            for _ in 0..200 {
                w.step(dt);
            }
        });
        assert_eq!(
            n, 0,
            "{n} heap allocations in 200 steps with a capsule in contact"
        );
    });
}

#[test]
fn constrained_rigid_and_volume_steps_allocate_nothing() {
    // The other step paths: a second cube stepped as a rigid body, a pinned corner and
    // volume preservation on the soft cube.
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let mut w = dropped_cube(0.05);
    let (_, _, lattice) = fitted_box([0.6, 0.3, 0.0], [0.8, 0.5, 0.2], 3);
    let m = Material::preset("rubber").unwrap();
    let block = w.add_lattice_body("block", &lattice, &m, Vector3::zeros());
    let range = w.bodies[block.0].nodes.clone();
    w.rigid
        .push(RigidBody::from_nodes(block.0, &w.nodes, range).unwrap());
    w.preserve_volume(BodyHandle(0), 1.0).unwrap();
    w.pin(&[0]).unwrap();
    for f in 1..=6 {
        w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
    }
    let n = allocations_in(|| {
        for f in 7..=12 {
            w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        }
    });
    assert_eq!(n, 0, "{n} heap allocations in 6 frames");
}

#[test]
fn newmark_steps_allocate_nothing() {
    // The same bounce under Newmark-β (predictor-corrector, then the dispersion and the
    // deformation damping after the corrector).
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let mut w = dropped_cube(0.05);
    w.settings.integrator = Integrator::newmark();
    warm_up_through_the_impact(&mut w);
    let n = allocations_in(|| {
        for f in 7..=12 {
            w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        }
    });
    assert_eq!(n, 0, "{n} heap allocations in 6 Newmark frames");
}
