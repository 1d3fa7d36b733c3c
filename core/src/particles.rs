//! Particle effects (Terasawa 1993 §2.3: explosion, water, splash, smoke): point masses with a
//! birth and a death, emitted by `[[emitter]]` sources and integrated like `kind = "particle"`
//! bodies — translation only, gravity, linear drag, bouncing off the floor and walls with
//! restitution and Coulomb friction.
//!
//! Emitters ([`EmitterSection`]):
//! - `explosion` (§2.3.1): a burst of `count` particles on a sphere of `radius` around the
//!   centre, flying outward at a random speed in `speed`;
//! - `fountain` (§2.3.2): `rate` particles a second from a disc of `radius` across
//!   `direction`, each within `spread` degrees of it;
//! - `splash` (§2.3.3): `rate` a second from a ring of `radius` around the centre, outward and
//!   up along `direction` at `spread` degrees above the ring's plane — with `follow` the ring
//!   rides on a body;
//! - `smoke` (§2.3.4): an explosion whose particles grow (`size`) and fade (`opacity`) with age.
//!
//! Everything is in simulation metres and seconds. The same emitters, seeds and frames give
//! the same particles, bit for bit: one random stream per emitter, particles kept in birth
//! order, integrated in a fixed number of substeps per frame.

use crate::solver::Plane;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

type V3 = Vector3<f64>;

/// Substeps per output frame of the particles' integration.
pub const PARTICLE_SUBSTEPS: usize = 8;
/// Most particles alive at once, all emitters together (about 100 bytes each).
pub const MAX_PARTICLES: usize = 2_000_000;

/// What an emitter emits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum EmitterKind {
    #[default]
    Explosion,
    Fountain,
    Splash,
    Smoke,
}

/// The shape a particle is drawn as where a format or a viewer needs geometry: an
/// octahedron of radius 1 (scaled to half the particle's width), its corners and its
/// outward, counter-clockwise faces.
pub const OCTAHEDRON_CORNERS: [[f32; 3]; 6] = [
    [1.0, 0.0, 0.0],
    [-1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, -1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.0, 0.0, -1.0],
];
pub const OCTAHEDRON_FACES: [[u32; 3]; 8] = [
    [0, 2, 4],
    [2, 1, 4],
    [1, 3, 4],
    [3, 0, 4],
    [2, 0, 5],
    [1, 2, 5],
    [3, 1, 5],
    [0, 3, 5],
];

/// `[[emitter]]`: a particle source (module docs).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct EmitterSection {
    #[serde(default)]
    pub name: Option<String>,
    #[serde(default)]
    pub kind: EmitterKind,
    /// Centre, m (the followed body's centre of mass is added when `follow` is set).
    #[serde(default)]
    pub position: [f64; 3],
    /// Name of a body whose centre of mass carries the emitter.
    #[serde(default)]
    pub follow: Option<String>,
    /// Main direction (fountain: the jet; splash: up). Default: the scene's up.
    #[serde(default)]
    pub direction: Option<[f64; 3]>,
    /// Particles of a burst (explosion, smoke).
    #[serde(default = "default_count")]
    pub count: usize,
    /// Particles a second (fountain, splash).
    #[serde(default = "default_rate")]
    pub rate: f64,
    /// When the emitter starts (a burst goes off), s.
    #[serde(default)]
    pub start: f64,
    /// When a stream stops, s (default: never).
    #[serde(default)]
    pub stop: Option<f64>,
    /// Wait for an event's `start_emitter` (its `start` is not used then).
    #[serde(default)]
    pub wait_for_event: bool,
    /// Sphere, disc or ring radius, m.
    #[serde(default = "default_radius")]
    pub radius: f64,
    /// Launch speed range, m/s.
    #[serde(default = "default_speed")]
    pub speed: [f64; 2],
    /// Fountain: half-angle of the jet's cone; splash: elevation above the ring's plane, °.
    #[serde(default = "default_spread")]
    pub spread: f64,
    /// Lifetime range, s.
    #[serde(default = "default_lifetime")]
    pub lifetime: [f64; 2],
    /// Width at birth and at death, m.
    #[serde(default = "default_size")]
    pub size: [f64; 2],
    /// Opacity at birth and at death.
    #[serde(default = "default_opacity")]
    pub opacity: [f64; 2],
    /// Linear air drag, 1/s (smoke defaults to 2, the others to 0).
    #[serde(default)]
    pub drag: Option<f64>,
    /// Bounce off the floor, walls and colliders: normal restitution and Coulomb friction.
    #[serde(default = "default_restitution")]
    pub restitution: f64,
    #[serde(default = "default_friction")]
    pub friction: f64,
    /// Seed of the emitter's random stream.
    #[serde(default)]
    pub seed: u64,
    /// Draw each particle as a streak along its motion too (§2.3.2's water; default: on for
    /// fountains, off for the others).
    #[serde(default)]
    pub streaks: Option<bool>,
}

fn default_count() -> usize {
    500
}
fn default_rate() -> f64 {
    200.0
}
fn default_radius() -> f64 {
    0.05
}
fn default_speed() -> [f64; 2] {
    [2.0, 4.0]
}
fn default_spread() -> f64 {
    15.0
}
fn default_lifetime() -> [f64; 2] {
    [1.0, 2.0]
}
fn default_size() -> [f64; 2] {
    [0.02, 0.02]
}
fn default_opacity() -> [f64; 2] {
    [1.0, 1.0]
}
fn default_restitution() -> f64 {
    0.4
}
fn default_friction() -> f64 {
    0.3
}

impl EmitterSection {
    /// What is wrong with the section (`what` names it in the message), if anything.
    pub fn check(&self, what: &str) -> Result<(), String> {
        let range = |name: &str, r: [f64; 2], low: f64| {
            if r.iter().all(|x| x.is_finite() && *x >= low) && r[0] <= r[1] {
                Ok(())
            } else {
                Err(format!(
                    "{what}.{name} must be [low, high] with {low} ≤ low ≤ high, got {r:?}"
                ))
            }
        };
        range("speed", self.speed, 0.0)?;
        range("lifetime", self.lifetime, 1e-6)?;
        range(
            "size",
            [
                self.size[0].min(self.size[1]),
                self.size[0].max(self.size[1]),
            ],
            0.0,
        )?;
        let finite = |name: &str, x: f64, low: f64| {
            if x.is_finite() && x >= low {
                Ok(())
            } else {
                Err(format!("{what}.{name} must be a number ≥ {low}, got {x}"))
            }
        };
        finite("rate", self.rate, 0.0)?;
        finite("start", self.start, 0.0)?;
        finite("radius", self.radius, 0.0)?;
        finite("spread", self.spread, 0.0)?;
        finite("restitution", self.restitution, 0.0)?;
        finite("friction", self.friction, 0.0)?;
        finite("drag", self.drag.unwrap_or(0.0), 0.0)?;
        if self.opacity.iter().any(|o| !(0.0..=1.0).contains(o)) {
            return Err(format!(
                "{what}.opacity must lie in [0, 1], got {:?}",
                self.opacity
            ));
        }
        if self.position.iter().any(|x| !x.is_finite()) {
            return Err(format!("{what}.position must be finite"));
        }
        if let Some(d) = self.direction {
            if !d.iter().all(|x| x.is_finite()) || V3::from(d).norm() == 0.0 {
                return Err(format!(
                    "{what}.direction must be a non-zero vector, got {d:?}"
                ));
            }
        }
        if self.count > MAX_PARTICLES {
            return Err(format!(
                "{what}.count {} exceeds {MAX_PARTICLES}",
                self.count
            ));
        }
        Ok(())
    }
}

/// How far in front of a collider's face a particle that hit it is put back, m.
const COLLIDER_SKIN: f64 = 1e-6;

/// The particles of one emitter at one output frame, in birth order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ParticleFrame {
    /// Stable per emitter: the n-th particle it emitted.
    pub ids: Vec<u64>,
    pub positions: Vec<[f32; 3]>,
    pub widths: Vec<f32>,
    pub opacities: Vec<f32>,
}

/// What the particles move in at a substep.
pub struct ParticleEnv<'a> {
    pub gravity: V3,
    pub up: V3,
    pub planes: &'a [Plane],
    /// Per emitter: the followed body's centre of mass now, when it follows one.
    pub follow: &'a [Option<V3>],
    /// The scene's static colliders, when it has any.
    pub colliders: Option<&'a crate::particle_colliders::TriangleGrid>,
}

struct Emitter {
    spec: EmitterSection,
    rng: fastrand::Rng,
    /// Particles emitted so far (the next particle's id).
    emitted: u64,
    /// Of those, the ones emitted before the stream was last started.
    before_start: u64,
    /// A burst emitter has gone off.
    fired: bool,
}

/// Every emitter's live particles, structure of arrays.
pub struct ParticleSystem {
    emitters: Vec<Emitter>,
    position: Vec<V3>,
    velocity: Vec<V3>,
    birth: Vec<f64>,
    death: Vec<f64>,
    id: Vec<u64>,
    emitter: Vec<u32>,
}

impl ParticleSystem {
    pub fn new(specs: &[EmitterSection]) -> ParticleSystem {
        ParticleSystem {
            emitters: specs
                .iter()
                .map(|spec| {
                    let mut spec = spec.clone();
                    if spec.wait_for_event {
                        spec.start = f64::INFINITY;
                    }
                    Emitter {
                        rng: fastrand::Rng::with_seed(spec.seed),
                        spec,
                        emitted: 0,
                        before_start: 0,
                        fired: false,
                    }
                })
                .collect(),
            position: Vec::new(),
            velocity: Vec::new(),
            birth: Vec::new(),
            death: Vec::new(),
            id: Vec::new(),
            emitter: Vec::new(),
        }
    }

    /// Particles alive now.
    pub fn len(&self) -> usize {
        self.position.len()
    }

    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }

    /// Emits and integrates from `time` for `frame_dt` seconds.
    pub fn advance(&mut self, time: f64, frame_dt: f64, env: &ParticleEnv) {
        let dt = frame_dt / PARTICLE_SUBSTEPS as f64;
        for k in 0..PARTICLE_SUBSTEPS {
            let t = time + k as f64 * dt;
            self.emit(t, dt, env);
            self.integrate(dt, env);
            self.retire(t + dt);
        }
    }

    /// Emits what is due by `time` (the first frame: call with `dt` 0).
    pub fn emit(&mut self, time: f64, dt: f64, env: &ParticleEnv) {
        for e in 0..self.emitters.len() {
            let centre = V3::from(self.emitters[e].spec.position)
                + env
                    .follow
                    .get(e)
                    .copied()
                    .flatten()
                    .unwrap_or_else(V3::zeros);
            let emitter = &mut self.emitters[e];
            let spec = &emitter.spec;
            let due = match spec.kind {
                EmitterKind::Explosion | EmitterKind::Smoke => {
                    if emitter.fired || time + dt < spec.start {
                        0
                    } else {
                        emitter.fired = true;
                        spec.count as u64
                    }
                }
                EmitterKind::Fountain | EmitterKind::Splash => {
                    let end = (time + dt).min(spec.stop.unwrap_or(f64::INFINITY));
                    let total = ((end - spec.start) * spec.rate).max(0.0).floor() as u64;
                    total.saturating_sub(emitter.emitted - emitter.before_start)
                }
            };
            let room = MAX_PARTICLES.saturating_sub(self.position.len()) as u64;
            for _ in 0..due.min(room) {
                self.spawn(e, centre, time, env.up);
            }
        }
    }

    fn spawn(&mut self, e: usize, centre: V3, time: f64, up: V3) {
        let emitter = &mut self.emitters[e];
        let spec = &emitter.spec;
        let rng = &mut emitter.rng;
        let mut uniform = |r: [f64; 2]| r[0] + (r[1] - r[0]) * rng.f64();
        let axis = spec.direction.map(V3::from).unwrap_or(up).normalize();
        let speed = uniform(spec.speed);
        let lifetime = uniform(spec.lifetime);
        let (offset, direction) = match spec.kind {
            EmitterKind::Explosion | EmitterKind::Smoke => {
                let d = sphere_point(uniform([-1.0, 1.0]), uniform([0.0, 1.0]));
                (d * spec.radius, d)
            }
            EmitterKind::Fountain => {
                let (u, w) = basis(&axis);
                let (r, a) = (
                    spec.radius * uniform([0.0, 1.0]).sqrt(),
                    uniform([0.0, 1.0]),
                );
                let at = (u * (a * std::f64::consts::TAU).cos()
                    + w * (a * std::f64::consts::TAU).sin())
                    * r;
                let cos_max = spec.spread.to_radians().cos();
                let cos = uniform([cos_max, 1.0]);
                let turn = uniform([0.0, std::f64::consts::TAU]);
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                (at, axis * cos + (u * turn.cos() + w * turn.sin()) * sin)
            }
            EmitterKind::Splash => {
                let (u, w) = basis(&axis);
                let turn = uniform([0.0, std::f64::consts::TAU]);
                let out = u * turn.cos() + w * turn.sin();
                let rise = uniform([0.5, 1.0]) * spec.spread.to_radians();
                (out * spec.radius, out * rise.cos() + axis * rise.sin())
            }
        };
        self.position.push(centre + offset);
        self.velocity.push(direction * speed);
        self.birth.push(time);
        self.death.push(time + lifetime);
        self.id.push(emitter.emitted);
        self.emitter.push(e as u32);
        emitter.emitted += 1;
    }

    fn integrate(&mut self, dt: f64, env: &ParticleEnv) {
        let ParticleSystem {
            emitters,
            position,
            velocity,
            emitter,
            ..
        } = self;
        for ((x, v), &e) in position
            .iter_mut()
            .zip(velocity.iter_mut())
            .zip(emitter.iter())
        {
            let spec = &emitters[e as usize].spec;
            *v += (env.gravity - *v * drag_of(spec)) * dt;
            let from = *x;
            *x += *v * dt;
            if let Some(hit) = env.colliders.and_then(|c| c.crossing(&from, x)) {
                // Back on the collider's face it came from, bounced off it.
                *x = hit.point + hit.normal * COLLIDER_SKIN;
                *v = bounce(*v, &hit.normal, spec.restitution, spec.friction);
            }
            for plane in env.planes {
                let depth = plane.offset - plane.normal.dot(x);
                if depth > 0.0 {
                    *x += plane.normal * depth;
                    *v = bounce(*v, &plane.normal, spec.restitution, spec.friction);
                }
            }
        }
    }

    /// Removes the particles whose death has come by `time`, keeping birth order.
    fn retire(&mut self, time: f64) {
        let mut keep = 0;
        for i in 0..self.position.len() {
            if self.death[i] > time {
                self.position.swap(keep, i);
                self.velocity.swap(keep, i);
                self.birth.swap(keep, i);
                self.death.swap(keep, i);
                self.id.swap(keep, i);
                self.emitter.swap(keep, i);
                keep += 1;
            }
        }
        for v in [&mut self.birth, &mut self.death] {
            v.truncate(keep);
        }
        self.position.truncate(keep);
        self.velocity.truncate(keep);
        self.id.truncate(keep);
        self.emitter.truncate(keep);
    }

    /// Every emitter's live particles at `time`, through `to_output` (simulation metres to
    /// the output's frame).
    pub fn snapshot(&self, time: f64, to_output: impl Fn(&V3) -> [f32; 3]) -> Vec<ParticleFrame> {
        let mut frames = vec![ParticleFrame::default(); self.emitters.len()];
        for i in 0..self.position.len() {
            let e = self.emitter[i] as usize;
            let spec = &self.emitters[e].spec;
            let age = ((time - self.birth[i]) / (self.death[i] - self.birth[i])).clamp(0.0, 1.0);
            let lerp = |r: [f64; 2]| (r[0] + (r[1] - r[0]) * age) as f32;
            let f = &mut frames[e];
            f.ids.push(self.id[i]);
            f.positions.push(to_output(&self.position[i]));
            f.widths.push(lerp(spec.size));
            f.opacities.push(lerp(spec.opacity));
        }
        frames
    }

    /// The emitters' names (given, else `<kind>_<index>`).
    /// An event's `start_emitter`: the named emitter starts at `time` (a burst goes off
    /// again, a stream begins or resumes). False when no emitter has the name.
    pub fn start_emitter(&mut self, name: &str, time: f64) -> bool {
        let Some(e) = self.names().iter().position(|n| n == name) else {
            return false;
        };
        let emitter = &mut self.emitters[e];
        emitter.spec.start = time;
        emitter.spec.stop = emitter.spec.stop.filter(|&s| s > time);
        emitter.fired = false;
        emitter.before_start = emitter.emitted;
        true
    }

    /// An event's `stop_emitter`: the named emitter's stream stops at `time`. False when no
    /// emitter has the name.
    pub fn stop_emitter(&mut self, name: &str, time: f64) -> bool {
        let Some(e) = self.names().iter().position(|n| n == name) else {
            return false;
        };
        self.emitters[e].spec.stop = Some(time);
        true
    }

    /// Per emitter: whether its particles are drawn as streaks too (`streaks`, default on
    /// for fountains).
    pub fn streaks(&self) -> Vec<bool> {
        self.emitters
            .iter()
            .map(|e| {
                e.spec
                    .streaks
                    .unwrap_or(e.spec.kind == EmitterKind::Fountain)
            })
            .collect()
    }

    pub fn names(&self) -> Vec<String> {
        self.emitters
            .iter()
            .enumerate()
            .map(|(i, e)| {
                e.spec.name.clone().unwrap_or_else(|| {
                    format!("{}_{i}", format!("{:?}", e.spec.kind).to_lowercase())
                })
            })
            .collect()
    }
}

/// Velocity after hitting a surface of normal `n`: the approach reversed times `restitution`,
/// the sliding slowed by Coulomb friction (the impulse `friction` times the normal one).
fn bounce(v: V3, n: &V3, restitution: f64, friction: f64) -> V3 {
    let vn = v.dot(n);
    if vn >= 0.0 {
        return v;
    }
    let tangential = v - n * vn;
    let slide = tangential.norm();
    let stop = friction * (1.0 + restitution) * -vn;
    let kept = if slide > 0.0 {
        (1.0 - stop / slide).max(0.0)
    } else {
        0.0
    };
    tangential * kept - n * (vn * restitution)
}

fn drag_of(spec: &EmitterSection) -> f64 {
    spec.drag.unwrap_or(match spec.kind {
        EmitterKind::Smoke => 2.0,
        _ => 0.0,
    })
}

/// A uniform point on the unit sphere from `z` in [−1, 1] and `a` in [0, 1).
fn sphere_point(z: f64, a: f64) -> V3 {
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = a * std::f64::consts::TAU;
    V3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Two unit vectors perpendicular to `axis` and to each other.
fn basis(axis: &V3) -> (V3, V3) {
    let helper = if axis.x.abs() < 0.9 { V3::x() } else { V3::y() };
    let u = axis.cross(&helper).normalize();
    (u, axis.cross(&u))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(kind: EmitterKind) -> EmitterSection {
        toml::from_str::<EmitterSection>(&format!("kind = \"{kind:?}\"").to_lowercase()).unwrap()
    }

    fn env<'a>(planes: &'a [Plane]) -> ParticleEnv<'a> {
        ParticleEnv {
            gravity: V3::new(0.0, -9.81, 0.0),
            up: V3::y(),
            planes,
            follow: &[],
            colliders: None,
        }
    }

    #[test]
    fn an_explosion_flies_outward_and_lands_on_the_floor() {
        let mut s = spec(EmitterKind::Explosion);
        s.position = [0.0, 1.0, 0.0];
        s.lifetime = [10.0, 10.0];
        let floor = [Plane {
            normal: V3::y(),
            offset: 0.0,
        }];
        let mut p = ParticleSystem::new(&[s]);
        p.emit(0.0, 0.0, &env(&floor));
        assert_eq!(p.len(), 500);
        for (x, v) in p.position.iter().zip(&p.velocity) {
            let out = x - V3::new(0.0, 1.0, 0.0);
            assert!((out.norm() - 0.05).abs() < 1e-12);
            assert!(out.normalize().dot(&v.normalize()) > 0.999999, "outward");
        }
        for f in 0..120 {
            p.advance(f as f64 / 24.0, 1.0 / 24.0, &env(&floor));
        }
        assert!(p.position.iter().all(|x| x.y >= 0.0));
        let resting = p.position.iter().filter(|x| x.y < 0.01).count();
        assert!(resting > 400, "{resting} of 500 on the floor after 5 s");
    }

    #[test]
    fn the_same_seed_gives_the_same_particles_and_ids_follow_birth() {
        let mut s = spec(EmitterKind::Fountain);
        s.rate = 240.0;
        let run = |s: &EmitterSection| {
            let mut p = ParticleSystem::new(std::slice::from_ref(s));
            for f in 0..24 {
                p.advance(f as f64 / 24.0, 1.0 / 24.0, &env(&[]));
            }
            p.snapshot(1.0, |x| [x.x as f32, x.y as f32, x.z as f32])
        };
        let a = run(&s);
        assert_eq!(a, run(&s));
        assert_eq!(a[0].ids.len(), 240, "one second at 240/s, lifetime ≥ 1 s");
        assert!(a[0].ids.windows(2).all(|w| w[0] < w[1]));
        s.seed = 7;
        assert_ne!(a, run(&s));
    }

    #[test]
    fn smoke_grows_and_fades_and_dies() {
        let mut s = spec(EmitterKind::Smoke);
        s.size = [0.01, 0.2];
        s.opacity = [1.0, 0.0];
        s.lifetime = [1.0, 1.0];
        let mut p = ParticleSystem::new(&[s]);
        p.emit(0.0, 0.0, &env(&[]));
        let at = |p: &ParticleSystem, t| p.snapshot(t, |_| [0.0; 3]).remove(0);
        p.advance(0.0, 0.5, &env(&[]));
        let half = at(&p, 0.5);
        assert!(half.widths.iter().all(|w| (w - 0.105).abs() < 1e-6));
        assert!(half.opacities.iter().all(|o| (o - 0.5).abs() < 1e-6));
        p.advance(0.5, 0.6, &env(&[]));
        assert!(p.is_empty(), "dead after their lifetime");
    }

    #[test]
    fn bad_sections_are_named() {
        let mut s = spec(EmitterKind::Fountain);
        s.lifetime = [2.0, 1.0];
        let e = s.check("emitter[0]").unwrap_err();
        assert!(e.contains("emitter[0].lifetime"), "{e}");
        s.lifetime = [1.0, 2.0];
        s.direction = Some([0.0, 0.0, 0.0]);
        assert!(s.check("emitter[0]").unwrap_err().contains("direction"));
    }
}
