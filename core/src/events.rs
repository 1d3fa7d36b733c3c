//! Motion-feature events and procedures (physics §11; Terasawa 1993, §4.4).
//!
//! This module owns a deterministic event queue that is independent of the solver: the solver
//! (or any driver) reports what happened in each output frame as an [`Observation`] and
//! [`EventQueue::observe`] answers with the [`Firing`]s, each a [`Procedure`] to apply to a
//! body. The queue never touches bodies itself: [`crate::procedures`] applies the firings to a
//! world, and the pipeline wires the scene file's `[[event]]` tables (the [`EventsFile`] form)
//! and the solver's contact log to it.
//!
//! # Events
//!
//! An event has a unique `name`, the `body` it belongs to (the body its procedures act on), a
//! trigger `on`, and either `procedure` (one procedure or an array, run in order) or `branch`.
//!
//! | trigger (`on = { … }`) | fires at the first observation where |
//! |---|---|
//! | `time = 0.5` | `time_secs ≥ 0.5 − 1e-9` (the tolerance absorbs `frame / fps` rounding) |
//! | `frame = 12` | `frame ≥ 12` |
//! | `collision = "lane"` | `body` collides with `lane` (either side of the reported pair); `"*"` = with anything |
//! | `convergence = 0.3` | `body` rebounds with a speed < 0.3 m/s ("rebounds fell under the bound") |
//!
//! Flags:
//! - `loop = true`: the event stays queued after firing and fires again at every later
//!   observation that satisfies it (so `on = { frame = 0 }, loop = true` fires every frame).
//!   Without it an event fires once and is done.
//! - `group = "g"`: related events (thesis fig 4.22). When members of a group fire, every other
//!   member is withdrawn. A firing member stays queued only if it is `loop` and it was the only
//!   member of its group to fire in that observation.
//! - `after = "other"`: the event is armed only from the observation after `other` first fired
//!   (thesis fig 4.20: E1 → P1, then wait for E2). If `other` is withdrawn before it fires, the
//!   dependent is withdrawn too.
//! - `branch`: choose the procedure by a quantity of the triggering observation (thesis fig 4.27:
//!   small / medium / large impact force → land / bounce / break through). `by` is
//!   `impact_force` (N) or `impact_speed` (m/s) for collision events, `rebound_speed` (m/s) for
//!   convergence events. Cases are tried in order; a case matches when the value is `< below`;
//!   `below` must increase strictly; only the last case may omit `below` (the "otherwise"). If
//!   no case matches the event does not fire and stays queued.
//!
//! # Simultaneous events and order independence
//!
//! All events are tested against the queue *as it was before* the observation, so events
//! stacked on the same observation fire together whatever their declaration order; group
//! withdrawal and `after` arming take effect afterwards. Among several collisions of one body in
//! one observation the strongest (largest impact force, then speed, then the other body's name)
//! is the one a collision event reports; among several rebounds, the slowest. The order of the
//! lists inside an [`Observation`] therefore never matters. The returned firings are sorted by
//! a stable key: event declaration order, then procedure order within the event.
//!
//! # Procedures
//!
//! `procedure = "pin"` | `"unpin"` | `"settle"`, or a one-key table:
//! `{ apply_force = { force_n = [0, -9.81, 0], duration_secs = 0.1 } }` (`duration_secs`
//! omitted = for the current frame), `{ apply_impulse = [0, 2, 0] }` (N·s),
//! `{ set_velocity = [3, 4, 0] }` (m/s; the "throw"), `{ switch_feature = "bounce" }` (`throw`,
//! `bounce`, `roll`, `collide`), `{ change_material = "rubber" }`,
//! `{ follow_trajectory = "arc" }`, `{ volume_scale = 0.8 }` (squash and stretch),
//! `{ anticipate = { velocity = [0, 0, -6], pull_back_m = 0.05, duration_secs = 0.2 } }`,
//! `{ plugin = { name = "my_procedure", args = { … } } }` (a procedure a plug-in registered).
//! What each does to a body is documented in [`crate::procedures`].
//!
//! # Example (the thesis's bowling ball, fig 4.28)
//!
//! ```toml
//! [[event]]
//! name = "throw"
//! body = "ball"
//! on = { time = 0.0 }
//! procedure = [{ switch_feature = "throw" }, { set_velocity = [0.0, 0.0, -8.0] }]
//!
//! [[event]]
//! name = "hit_lane"
//! body = "ball"
//! on = { collision = "lane" }
//! after = "throw"
//! branch.by = "impact_force"
//! branch.case = [
//!   { below = 50.0, procedure = "settle" },
//!   { below = 500.0, procedure = { switch_feature = "bounce" } },
//!   { procedure = { change_material = "shards" } },
//! ]
//!
//! [[event]]
//! name = "settled"
//! body = "ball"
//! on = { convergence = 0.2 }
//! procedure = { switch_feature = "roll" }
//!
//! [[event]]
//! name = "hit_pin"
//! body = "ball"
//! on = { collision = "pin" }
//! loop = true
//! procedure = { switch_feature = "collide" }
//! ```
//!
//! A [`Firing`] serialises as `{ "frame": 12, "body": "ball", "event": "hit_lane",
//! "procedure": { "switch_feature": "bounce" } }` (unit procedures as a string: `"settle"`).

use serde::de::{self, IntoDeserializer, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::cmp::Ordering;
use std::collections::{BTreeMap, HashMap};
use std::fmt;

/// Slack on time triggers, s: `frame as f64 / fps` may land a hair under the intended time.
pub const TIME_EPSILON_SECS: f64 = 1e-9;

/// The thesis's motion features (§4.1, physics §11).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionFeature {
    /// Dynamics only.
    Throw,
    /// Collision response until rebounds fall under a tolerance, then settle.
    Bounce,
    /// Geometric path, initial speed from the previous feature.
    Roll,
    /// Detection and response (optionally volume preserving).
    Collide,
}

/// What a firing asks the driver to do to its body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Procedure {
    /// A force in newtons, world frame, on the whole body; `duration_secs` omitted = the current
    /// frame only.
    ApplyForce {
        force_n: [f64; 3],
        #[serde(default, skip_serializing_if = "Option::is_none")]
        duration_secs: Option<f64>,
    },
    /// An impulse in N·s, world frame.
    ApplyImpulse([f64; 3]),
    /// Set the body's velocity, m/s (the "throw").
    SetVelocity([f64; 3]),
    SwitchFeature(MotionFeature),
    /// Swap the material by preset or scene name.
    ChangeMaterial(String),
    /// Hold the body where it is.
    Pin,
    Unpin,
    /// Stop bouncing and settle geometrically (end of the bounce feature).
    Settle,
    /// Follow the named trajectory (physics §9).
    FollowTrajectory(String),
    /// Squash and stretch: drive the body's volume towards this multiple of its rest volume
    /// (Terasawa §3.2, §4.2.1).
    VolumeScale(f64),
    /// Anticipation (Terasawa §4.2.2): pull the body's trailing part back against the coming
    /// throw for `duration_secs`, then set its velocity to `velocity` (m/s).
    Anticipate {
        velocity: [f64; 3],
        /// How far the trailing nodes are drawn back, m.
        pull_back_m: f64,
        duration_secs: f64,
    },
    /// Start the named `[[emitter]]` now: a burst goes off, a stream begins (the host's
    /// particles; the body is not changed).
    StartEmitter(String),
    /// Stop the named `[[emitter]]`'s stream now.
    StopEmitter(String),
    /// A procedure registered by a plug-in on the host's registry, by name, with its own
    /// arguments (see `crate::procedures::ProcedurePlugin`).
    Plugin {
        name: String,
        #[serde(default, skip_serializing_if = "toml::Table::is_empty")]
        args: toml::Table,
    },
}

/// When an event fires (`on = { … }` in TOML).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Trigger {
    /// Simulation time reached, s.
    Time(f64),
    /// Output frame reached.
    Frame(u64),
    /// The event's body collides with the named body (`None`, written `"*"`, = anything).
    Collision(#[serde(with = "any_body")] Option<String>),
    /// The event's body rebounds with a speed under this bound, m/s.
    Convergence(f64),
}

/// `"*"` ⇄ `None`, any other string ⇄ `Some(name)`.
mod any_body {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &Option<String>, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(v.as_deref().unwrap_or("*"))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<String>, D::Error> {
        let s = String::deserialize(d)?;
        Ok(if s == "*" { None } else { Some(s) })
    }
}

/// The observed quantity a branch event switches on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BranchBy {
    /// Collision events: impact force, N.
    ImpactForce,
    /// Collision events: impact speed, m/s.
    ImpactSpeed,
    /// Convergence events: rebound speed, m/s.
    ReboundSpeed,
}

/// One case of a branch: taken when the value is `< below` (or always, without `below`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BranchCase {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub below: Option<f64>,
    #[serde(deserialize_with = "one_or_many")]
    pub procedure: Vec<Procedure>,
}

/// `branch = { by = "...", case = [...] }`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Branch {
    pub by: BranchBy,
    #[serde(rename = "case")]
    pub cases: Vec<BranchCase>,
}

/// One `[[event]]` table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EventSpec {
    pub name: String,
    pub body: String,
    pub on: Trigger,
    #[serde(
        default,
        deserialize_with = "one_or_many",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub procedure: Vec<Procedure>,
    #[serde(default, rename = "loop", skip_serializing_if = "is_false")]
    pub looping: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub after: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub branch: Option<Branch>,
}

fn is_false(b: &bool) -> bool {
    !*b
}

impl EventSpec {
    /// A one-shot event running `procedure`.
    pub fn new(name: impl Into<String>, body: impl Into<String>, on: Trigger) -> EventSpec {
        EventSpec {
            name: name.into(),
            body: body.into(),
            on,
            procedure: Vec::new(),
            looping: false,
            group: None,
            after: None,
            branch: None,
        }
    }

    pub fn procedure(mut self, p: Procedure) -> Self {
        self.procedure.push(p);
        self
    }

    pub fn looping(mut self) -> Self {
        self.looping = true;
        self
    }

    pub fn group(mut self, g: impl Into<String>) -> Self {
        self.group = Some(g.into());
        self
    }

    pub fn after(mut self, e: impl Into<String>) -> Self {
        self.after = Some(e.into());
        self
    }

    pub fn branch(mut self, by: BranchBy, cases: Vec<(Option<f64>, Procedure)>) -> Self {
        self.branch = Some(Branch {
            by,
            cases: cases
                .into_iter()
                .map(|(below, p)| BranchCase {
                    below,
                    procedure: vec![p],
                })
                .collect(),
        });
        self
    }
}

/// A procedure, or an array of procedures, as written in TOML.
fn one_or_many<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Procedure>, D::Error> {
    struct V;
    impl<'de> Visitor<'de> for V {
        type Value = Vec<Procedure>;
        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            f.write_str(
                "a procedure (\"pin\", \"unpin\", \"settle\" or a table such as \
                 { set_velocity = [0, 5, 0] }) or an array of procedures",
            )
        }
        fn visit_str<E: de::Error>(self, s: &str) -> Result<Self::Value, E> {
            Procedure::deserialize(s.into_deserializer()).map(|p| vec![p])
        }
        fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<Self::Value, A::Error> {
            Procedure::deserialize(de::value::MapAccessDeserializer::new(map)).map(|p| vec![p])
        }
        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
            let mut out = Vec::new();
            while let Some(p) = seq.next_element::<Procedure>()? {
                out.push(p);
            }
            Ok(out)
        }
    }
    d.deserialize_any(V)
}

/// A file (or scene section) of `[[event]]` tables.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EventsFile {
    #[serde(default)]
    pub event: Vec<EventSpec>,
}

/// A bad event description. `location` is a data path such as
/// `event[2] "hit_lane".branch.case[1].below`, or `line 7, column 3` for TOML syntax errors.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{location}: {message}")]
pub struct EventError {
    pub location: String,
    pub message: String,
    /// 1-based line and column for errors found while parsing TOML.
    pub line: Option<usize>,
    pub column: Option<usize>,
}

impl EventError {
    fn at(location: String, message: impl Into<String>) -> EventError {
        EventError {
            location,
            message: message.into(),
            line: None,
            column: None,
        }
    }
}

/// A collision seen during one frame. The pair is unordered for matching.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CollisionObservation {
    pub body: String,
    pub with: String,
    /// Relative normal speed at impact, m/s.
    pub impact_speed_m_s: f64,
    /// Peak impact force (e.g. Hertz `F_max`), N.
    pub impact_force_n: f64,
}

/// A rebound seen during one frame: the body's speed along the contact normal just after it
/// left the surface (for a bounce on the floor, its vertical speed).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReboundObservation {
    pub body: String,
    pub rebound_speed_m_s: f64,
}

/// What the driver saw in one output frame.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Observation {
    pub frame: u64,
    pub time_secs: f64,
    #[serde(default)]
    pub collisions: Vec<CollisionObservation>,
    #[serde(default)]
    pub rebounds: Vec<ReboundObservation>,
}

impl Observation {
    /// Frame `frame` at `fps` frames per second (`time_secs = frame / fps`).
    pub fn frame(frame: u64, fps: f64) -> Observation {
        Observation {
            frame,
            time_secs: frame as f64 / fps,
            ..Observation::default()
        }
    }

    pub fn with_collision(
        mut self,
        body: impl Into<String>,
        with: impl Into<String>,
        impact_speed_m_s: f64,
        impact_force_n: f64,
    ) -> Self {
        self.collisions.push(CollisionObservation {
            body: body.into(),
            with: with.into(),
            impact_speed_m_s,
            impact_force_n,
        });
        self
    }

    pub fn with_rebound(mut self, body: impl Into<String>, rebound_speed_m_s: f64) -> Self {
        self.rebounds.push(ReboundObservation {
            body: body.into(),
            rebound_speed_m_s,
        });
        self
    }
}

/// One procedure to run, in the report format `{ "frame", "body", "event", "procedure" }`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Firing {
    pub frame: u64,
    pub body: String,
    pub event: String,
    pub procedure: Procedure,
}

/// Where an event stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EventStatus {
    /// Waiting for its `after` event to fire.
    Waiting,
    /// Armed: will fire when its trigger holds.
    Queued,
    /// A one-shot event that fired.
    Done,
    /// Removed without firing (a related event fired, or its `after` event went away).
    Withdrawn,
}

impl Serialize for EventStatus {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(match self {
            EventStatus::Waiting => "waiting",
            EventStatus::Queued => "queued",
            EventStatus::Done => "done",
            EventStatus::Withdrawn => "withdrawn",
        })
    }
}

/// The event queue: validated events in declaration order and their status.
#[derive(Debug, Clone)]
pub struct EventQueue {
    events: Vec<EventSpec>,
    status: Vec<EventStatus>,
    fired: Vec<u64>,
    /// Index of each event's `after` event.
    after: Vec<Option<usize>>,
}

/// The observed values an event matched on.
#[derive(Debug, Clone, Copy)]
enum Matched {
    Plain,
    Collision { speed: f64, force: f64 },
    Rebound { speed: f64 },
}

fn finite_vec(v: &[f64; 3]) -> bool {
    v.iter().all(|x| x.is_finite())
}

fn validate_procedure(p: &Procedure, loc: &str) -> Result<(), EventError> {
    let bad = |m: &str| Err(EventError::at(loc.to_owned(), m.to_owned()));
    match p {
        Procedure::ApplyForce {
            force_n,
            duration_secs,
        } => {
            if !finite_vec(force_n) {
                return bad("apply_force.force_n must be finite");
            }
            if let Some(d) = duration_secs {
                if !(d.is_finite() && *d > 0.0) {
                    return bad("apply_force.duration_secs must be finite and > 0");
                }
            }
        }
        Procedure::ApplyImpulse(v) | Procedure::SetVelocity(v) => {
            if !finite_vec(v) {
                return bad("vector components must be finite");
            }
        }
        Procedure::ChangeMaterial(n)
        | Procedure::FollowTrajectory(n)
        | Procedure::StartEmitter(n)
        | Procedure::StopEmitter(n) => {
            if n.trim().is_empty() {
                return bad("name must not be empty");
            }
        }
        Procedure::VolumeScale(s) => {
            if !(s.is_finite() && *s > 0.0) {
                return bad("volume_scale must be finite and > 0");
            }
        }
        Procedure::Anticipate {
            velocity,
            pull_back_m,
            duration_secs,
        } => {
            if !finite_vec(velocity) || velocity.iter().all(|c| *c == 0.0) {
                return bad("anticipate.velocity must be finite and not zero");
            }
            if !(pull_back_m.is_finite() && *pull_back_m > 0.0) {
                return bad("anticipate.pull_back_m must be finite and > 0");
            }
            if !(duration_secs.is_finite() && *duration_secs > 0.0) {
                return bad("anticipate.duration_secs must be finite and > 0");
            }
        }
        Procedure::Plugin { name, .. } => {
            if name.trim().is_empty() {
                return bad("plugin.name must not be empty");
            }
        }
        Procedure::SwitchFeature(_) | Procedure::Pin | Procedure::Unpin | Procedure::Settle => {}
    }
    Ok(())
}

impl EventQueue {
    /// Validate `events` (see the module doc) and queue them in this declaration order.
    pub fn new(events: Vec<EventSpec>) -> Result<EventQueue, EventError> {
        let mut index: HashMap<&str, usize> = HashMap::new();
        for (i, e) in events.iter().enumerate() {
            let loc = format!("event[{i}]");
            if e.name.trim().is_empty() {
                return Err(EventError::at(format!("{loc}.name"), "must not be empty"));
            }
            if let Some(j) = index.insert(e.name.as_str(), i) {
                return Err(EventError::at(
                    format!("{loc}.name"),
                    format!("\"{}\" is already the name of event[{j}]", e.name),
                ));
            }
        }
        let mut after = Vec::with_capacity(events.len());
        for (i, e) in events.iter().enumerate() {
            let loc = format!("event[{i}] \"{}\"", e.name);
            if e.body.trim().is_empty() {
                return Err(EventError::at(format!("{loc}.body"), "must not be empty"));
            }
            match &e.on {
                Trigger::Time(t) if !(t.is_finite() && *t >= 0.0) => {
                    return Err(EventError::at(
                        format!("{loc}.on.time"),
                        format!("must be finite and >= 0 s, got {t}"),
                    ));
                }
                Trigger::Convergence(b) if !(b.is_finite() && *b > 0.0) => {
                    return Err(EventError::at(
                        format!("{loc}.on.convergence"),
                        format!("must be finite and > 0 m/s, got {b}"),
                    ));
                }
                Trigger::Collision(Some(w)) if w.trim().is_empty() => {
                    return Err(EventError::at(
                        format!("{loc}.on.collision"),
                        "must name a body, or be \"*\" for any",
                    ));
                }
                _ => {}
            }
            match (&e.branch, e.procedure.is_empty()) {
                (None, true) => {
                    return Err(EventError::at(
                        loc,
                        "needs a `procedure` (or an array of them) or a `branch`",
                    ));
                }
                (Some(_), false) => {
                    return Err(EventError::at(
                        loc,
                        "has both `procedure` and `branch`; put the procedures in the branch cases",
                    ));
                }
                _ => {}
            }
            for (k, p) in e.procedure.iter().enumerate() {
                validate_procedure(p, &format!("{loc}.procedure[{k}]"))?;
            }
            if let Some(b) = &e.branch {
                Self::validate_branch(b, &e.on, &format!("{loc}.branch"))?;
            }
            if let Some(g) = &e.group {
                if g.trim().is_empty() {
                    return Err(EventError::at(format!("{loc}.group"), "must not be empty"));
                }
            }
            after.push(match &e.after {
                None => None,
                Some(a) => match index.get(a.as_str()) {
                    Some(&j) if j == i => {
                        return Err(EventError::at(
                            format!("{loc}.after"),
                            "an event cannot wait for itself",
                        ));
                    }
                    Some(&j) => Some(j),
                    None => {
                        return Err(EventError::at(
                            format!("{loc}.after"),
                            format!("no event is named \"{a}\""),
                        ));
                    }
                },
            });
        }
        // `after` chains must not loop: such events could never be armed.
        for start in 0..events.len() {
            let mut cur = after[start];
            let mut steps = 0;
            while let Some(j) = cur {
                if j == start || steps > events.len() {
                    return Err(EventError::at(
                        format!("event[{start}] \"{}\".after", events[start].name),
                        "the `after` chain loops back to this event",
                    ));
                }
                cur = after[j];
                steps += 1;
            }
        }
        let status = after
            .iter()
            .map(|a| {
                if a.is_some() {
                    EventStatus::Waiting
                } else {
                    EventStatus::Queued
                }
            })
            .collect();
        let n = events.len();
        Ok(EventQueue {
            events,
            status,
            fired: vec![0; n],
            after,
        })
    }

    fn validate_branch(b: &Branch, on: &Trigger, loc: &str) -> Result<(), EventError> {
        let fits = match b.by {
            BranchBy::ImpactForce | BranchBy::ImpactSpeed => matches!(on, Trigger::Collision(_)),
            BranchBy::ReboundSpeed => matches!(on, Trigger::Convergence(_)),
        };
        if !fits {
            return Err(EventError::at(
                format!("{loc}.by"),
                "impact_force and impact_speed need a collision trigger, rebound_speed a \
                 convergence trigger",
            ));
        }
        if b.cases.is_empty() {
            return Err(EventError::at(
                format!("{loc}.case"),
                "needs at least one case",
            ));
        }
        let mut prev = f64::NEG_INFINITY;
        let last = b.cases.len() - 1;
        for (k, c) in b.cases.iter().enumerate() {
            let cloc = format!("{loc}.case[{k}]");
            match c.below {
                Some(v) => {
                    if !v.is_finite() || v <= prev {
                        return Err(EventError::at(
                            format!("{cloc}.below"),
                            format!("must be finite and greater than the previous case's ({prev}), got {v}"),
                        ));
                    }
                    prev = v;
                }
                None if k != last => {
                    return Err(EventError::at(
                        format!("{cloc}.below"),
                        "only the last case may omit `below`",
                    ));
                }
                None => {}
            }
            if c.procedure.is_empty() {
                return Err(EventError::at(
                    format!("{cloc}.procedure"),
                    "needs at least one procedure",
                ));
            }
            for (j, p) in c.procedure.iter().enumerate() {
                validate_procedure(p, &format!("{cloc}.procedure[{j}]"))?;
            }
        }
        Ok(())
    }

    /// Parse the TOML form (`[[event]]` tables, see the module doc) and validate it.
    pub fn from_toml(text: &str) -> Result<EventQueue, EventError> {
        let file: EventsFile = toml::from_str(text).map_err(|e| {
            let (line, column) = crate::scene::toml_error_position(text, &e);
            EventError {
                location: match (line, column) {
                    (Some(l), Some(c)) => format!("line {l}, column {c}"),
                    _ => "events".to_owned(),
                },
                message: e.message().to_owned(),
                line,
                column,
            }
        })?;
        EventQueue::new(file.event)
    }

    /// The events in declaration order.
    pub fn events(&self) -> &[EventSpec] {
        &self.events
    }

    /// Status of the named event.
    pub fn status(&self, name: &str) -> Option<EventStatus> {
        self.index_of(name).map(|i| self.status[i])
    }

    /// How many observations the named event has fired on.
    pub fn fire_count(&self, name: &str) -> Option<u64> {
        self.index_of(name).map(|i| self.fired[i])
    }

    /// Names of the events still armed or waiting, in declaration order.
    pub fn pending(&self) -> Vec<&str> {
        self.events
            .iter()
            .zip(&self.status)
            .filter(|(_, s)| matches!(s, EventStatus::Queued | EventStatus::Waiting))
            .map(|(e, _)| e.name.as_str())
            .collect()
    }

    fn index_of(&self, name: &str) -> Option<usize> {
        self.events.iter().position(|e| e.name == name)
    }

    /// Does event `e` hold on `obs`, and on which values?
    fn matches(e: &EventSpec, obs: &Observation) -> Option<Matched> {
        match &e.on {
            Trigger::Time(t) => (obs.time_secs + TIME_EPSILON_SECS >= *t).then_some(Matched::Plain),
            Trigger::Frame(n) => (obs.frame >= *n).then_some(Matched::Plain),
            Trigger::Collision(with) => {
                let hits = obs.collisions.iter().filter_map(|c| {
                    let other = if c.body == e.body {
                        &c.with
                    } else if c.with == e.body {
                        &c.body
                    } else {
                        return None;
                    };
                    match with {
                        Some(w) if w != other => None,
                        _ => Some((c, other)),
                    }
                });
                // The strongest hit, independent of list order.
                hits.max_by(|(a, ao), (b, bo)| {
                    a.impact_force_n
                        .total_cmp(&b.impact_force_n)
                        .then(a.impact_speed_m_s.total_cmp(&b.impact_speed_m_s))
                        .then_with(|| bo.cmp(ao))
                })
                .map(|(c, _)| Matched::Collision {
                    speed: c.impact_speed_m_s,
                    force: c.impact_force_n,
                })
            }
            Trigger::Convergence(bound) => obs
                .rebounds
                .iter()
                .filter(|r| r.body == e.body && r.rebound_speed_m_s.abs() < *bound)
                .map(|r| r.rebound_speed_m_s.abs())
                .min_by(f64::total_cmp)
                .map(|speed| Matched::Rebound { speed }),
        }
    }

    /// The procedures event `e` runs for `m`, or `None` when no branch case holds.
    fn procedures(e: &EventSpec, m: Matched) -> Option<&[Procedure]> {
        let Some(b) = &e.branch else {
            return Some(&e.procedure);
        };
        let value = match (b.by, m) {
            (BranchBy::ImpactForce, Matched::Collision { force, .. }) => force,
            (BranchBy::ImpactSpeed, Matched::Collision { speed, .. }) => speed,
            (BranchBy::ReboundSpeed, Matched::Rebound { speed }) => speed,
            // Excluded by validation.
            _ => return None,
        };
        b.cases
            .iter()
            .find(|c| match c.below {
                Some(below) => value.partial_cmp(&below) == Some(Ordering::Less),
                None => true,
            })
            .map(|c| c.procedure.as_slice())
    }

    /// Feed one frame's observation; returns the procedures to run, sorted by event declaration
    /// order then procedure order. See the module doc for the exact semantics.
    pub fn observe(&mut self, obs: &Observation) -> Vec<Firing> {
        // 1. Test every armed event against the queue as it was before this observation.
        let mut fired_now: Vec<usize> = Vec::new();
        let mut firings = Vec::new();
        for (i, e) in self.events.iter().enumerate() {
            if self.status[i] != EventStatus::Queued {
                continue;
            }
            let Some(m) = Self::matches(e, obs) else {
                continue;
            };
            let Some(procs) = Self::procedures(e, m) else {
                continue;
            };
            fired_now.push(i);
            firings.extend(procs.iter().map(|p| Firing {
                frame: obs.frame,
                body: e.body.clone(),
                event: e.name.clone(),
                procedure: p.clone(),
            }));
        }
        // 2. Update the queue: loop / one-shot, then related groups.
        let mut per_group: BTreeMap<&str, usize> = BTreeMap::new();
        for &i in &fired_now {
            self.fired[i] += 1;
            if let Some(g) = &self.events[i].group {
                *per_group.entry(g.as_str()).or_default() += 1;
            }
        }
        let mut next = self.status.clone();
        for &i in &fired_now {
            let e = &self.events[i];
            let alone_in_group = e.group.as_deref().is_none_or(|g| per_group[g] == 1);
            next[i] = if e.looping && alone_in_group {
                EventStatus::Queued
            } else {
                EventStatus::Done
            };
        }
        for (i, e) in self.events.iter().enumerate() {
            let withdrawn_by_group = e
                .group
                .as_deref()
                .is_some_and(|g| per_group.contains_key(g))
                && !fired_now.contains(&i);
            if withdrawn_by_group && matches!(next[i], EventStatus::Queued | EventStatus::Waiting) {
                next[i] = EventStatus::Withdrawn;
            }
        }
        // 3. `after`: arm the dependents of events that fired; withdraw those whose
        //    predecessor can no longer fire. Repeat to follow chains.
        loop {
            let mut changed = false;
            for i in 0..self.events.len() {
                if next[i] != EventStatus::Waiting {
                    continue;
                }
                let Some(j) = self.after[i] else { continue };
                if fired_now.contains(&j) {
                    next[i] = EventStatus::Queued;
                    changed = true;
                } else if next[j] == EventStatus::Withdrawn {
                    next[i] = EventStatus::Withdrawn;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        self.status = next;
        firings
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_and_table_procedures_parse() {
        let q = EventQueue::from_toml(
            "[[event]]\nname = \"a\"\nbody = \"b\"\non = { frame = 1 }\nprocedure = \"pin\"\n\
             [[event]]\nname = \"c\"\nbody = \"b\"\non = { frame = 1 }\n\
             procedure = [\"unpin\", { apply_force = { force_n = [0, 1, 0] } }]\n",
        )
        .unwrap();
        assert_eq!(q.events()[0].procedure, vec![Procedure::Pin]);
        assert_eq!(
            q.events()[1].procedure,
            vec![
                Procedure::Unpin,
                Procedure::ApplyForce {
                    force_n: [0.0, 1.0, 0.0],
                    duration_secs: None
                }
            ]
        );
    }
}
