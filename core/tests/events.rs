//! The motion-feature event queue (physics §11, Terasawa §4.4): stacked events, loop events,
//! related groups, branch events, time / frame / collision / convergence triggers, `after`
//! chains, the TOML form and its errors, and the report format of a firing.

use springbake_core::events::*;

const FPS: f64 = 24.0;

fn fired(f: &[Firing]) -> Vec<(u64, &str, &str)> {
    f.iter()
        .map(|f| (f.frame, f.body.as_str(), f.event.as_str()))
        .collect()
}

/// Runs frames 0..frames, the observation of each frame built by `obs`.
fn run(q: &mut EventQueue, frames: u64, mut obs: impl FnMut(u64) -> Observation) -> Vec<Firing> {
    (0..frames).flat_map(|f| q.observe(&obs(f))).collect()
}

/// Three events stacked on one collision (two of them related), declared in two orders: the same
/// events fire with the same procedures. A naive queue that walks events in declaration order
/// and withdraws group members as it goes would let whichever related event comes first win.
#[test]
fn stacked_events_are_order_independent() {
    let specs = vec![
        EventSpec::new("squash", "ball", Trigger::Collision(Some("lane".into())))
            .procedure(Procedure::SwitchFeature(MotionFeature::Bounce))
            .group("landing"),
        EventSpec::new("recolour", "ball", Trigger::Collision(None))
            .procedure(Procedure::ChangeMaterial("red_rubber".into())),
        EventSpec::new("stop", "ball", Trigger::Collision(Some("lane".into())))
            .procedure(Procedure::Settle)
            .group("landing"),
        EventSpec::new("late", "ball", Trigger::Frame(5)).procedure(Procedure::Unpin),
    ];
    let frame = |f: u64| {
        let o = Observation::frame(f, FPS);
        if f == 3 {
            o.with_collision("ball", "lane", 4.0, 120.0)
        } else {
            o
        }
    };
    let mut forward = EventQueue::new(specs.clone()).unwrap();
    let mut reversed_specs = specs.clone();
    reversed_specs.reverse();
    let mut backward = EventQueue::new(reversed_specs).unwrap();
    let a = run(&mut forward, 8, frame);
    let b = run(&mut backward, 8, frame);

    // Sequence follows declaration order...
    assert_eq!(
        fired(&a),
        vec![
            (3, "ball", "squash"),
            (3, "ball", "recolour"),
            (3, "ball", "stop"),
            (5, "ball", "late")
        ]
    );
    assert_eq!(
        fired(&b),
        vec![
            (3, "ball", "stop"),
            (3, "ball", "recolour"),
            (3, "ball", "squash"),
            (5, "ball", "late")
        ]
    );
    // ...and the set of firings is the same either way.
    let key = |v: &[Firing]| {
        let mut v: Vec<String> = v
            .iter()
            .map(|f| serde_json::to_string(f).unwrap())
            .collect();
        v.sort();
        v
    };
    assert_eq!(key(&a), key(&b));
    for q in [&forward, &backward] {
        assert_eq!(q.status("squash"), Some(EventStatus::Done));
        assert_eq!(q.status("stop"), Some(EventStatus::Done));
        assert!(q.pending().is_empty(), "{:?}", q.pending());
    }

    // The order of collisions inside one observation does not matter either: the strongest hit
    // is the one a branch sees.
    let branchy = || {
        EventQueue::new(vec![EventSpec::new(
            "hit",
            "ball",
            Trigger::Collision(None),
        )
        .branch(
            BranchBy::ImpactForce,
            vec![
                (Some(100.0), Procedure::Settle),
                (None, Procedure::SwitchFeature(MotionFeature::Bounce)),
            ],
        )])
        .unwrap()
    };
    let o1 = Observation::frame(1, FPS)
        .with_collision("ball", "lane", 1.0, 20.0)
        .with_collision("pin", "ball", 2.0, 300.0);
    let mut o2 = o1.clone();
    o2.collisions.reverse();
    let f1 = branchy().observe(&o1);
    let f2 = branchy().observe(&o2);
    assert_eq!(f1, f2);
    assert_eq!(
        f1[0].procedure,
        Procedure::SwitchFeature(MotionFeature::Bounce)
    );
}

/// A loop event fires at every matching observation; a one-shot event only at the first.
#[test]
fn loop_events_fire_repeatedly() {
    let mut q = EventQueue::new(vec![
        EventSpec::new("gravity", "ball", Trigger::Frame(0))
            .procedure(Procedure::ApplyForce {
                force_n: [0.0, -9.81, 0.0],
                duration_secs: None,
            })
            .looping(),
        EventSpec::new("pins_react", "ball", Trigger::Collision(Some("pin".into())))
            .procedure(Procedure::SwitchFeature(MotionFeature::Collide))
            .looping(),
        EventSpec::new("first_pin", "ball", Trigger::Collision(Some("pin".into())))
            .procedure(Procedure::ChangeMaterial("scuffed".into())),
    ])
    .unwrap();
    let hits = [4u64, 9, 10, 15];
    let out = run(&mut q, 20, |f| {
        let o = Observation::frame(f, FPS);
        if hits.contains(&f) {
            // Reported from the pin's side: matching is symmetric.
            o.with_collision("pin", "ball", 1.5, 40.0)
        } else {
            o
        }
    });
    let frames_of = |name: &str| -> Vec<u64> {
        out.iter()
            .filter(|f| f.event == name)
            .map(|f| f.frame)
            .collect()
    };
    assert_eq!(frames_of("gravity"), (0..20).collect::<Vec<_>>());
    assert_eq!(frames_of("pins_react"), hits.to_vec());
    assert_eq!(frames_of("first_pin"), vec![4]);
    assert_eq!(q.fire_count("gravity"), Some(20));
    assert_eq!(q.fire_count("pins_react"), Some(4));
    assert_eq!(q.status("pins_react"), Some(EventStatus::Queued));
    assert_eq!(q.status("first_pin"), Some(EventStatus::Done));
}

/// Thesis fig 4.22–4.23: E1, E2, E4 wait together, E1 and E2 related; E2 fires → E1 withdrawn
/// (even though its own condition later holds), E4 unaffected. Members that hold on the same
/// observation fire together and end the group; a loop member firing alone stays queued and
/// withdraws the rest.
#[test]
fn related_events_are_withdrawn_together() {
    let mut q = EventQueue::new(vec![
        EventSpec::new("e1", "ball", Trigger::Time(1.0))
            .procedure(Procedure::Pin)
            .group("g1"),
        EventSpec::new("e2", "ball", Trigger::Collision(Some("wall".into())))
            .procedure(Procedure::SetVelocity([0.0, 3.0, 0.0]))
            .group("g1"),
        EventSpec::new("e4", "ball", Trigger::Frame(30)).procedure(Procedure::Unpin),
        // g2: both members hold at frame 6 and fire together; the loop one ends with them.
        EventSpec::new("spin", "top", Trigger::Frame(6))
            .procedure(Procedure::ApplyImpulse([0.0, 0.0, 0.1]))
            .looping()
            .group("g2"),
        EventSpec::new("topple", "top", Trigger::Frame(6))
            .procedure(Procedure::Settle)
            .group("g2"),
        // g3: a loop member that fires alone keeps firing and withdraws the other member.
        EventSpec::new("tick", "clock", Trigger::Frame(2))
            .procedure(Procedure::ApplyImpulse([0.0, 0.1, 0.0]))
            .looping()
            .group("g3"),
        EventSpec::new("alarm", "clock", Trigger::Frame(20))
            .procedure(Procedure::Pin)
            .group("g3"),
    ])
    .unwrap();
    let out = run(&mut q, 40, |f| {
        let o = Observation::frame(f, FPS);
        if f == 10 {
            o.with_collision("ball", "wall", 2.0, 10.0)
        } else {
            o
        }
    });
    let frames_of = |name: &str| -> Vec<u64> {
        out.iter()
            .filter(|f| f.event == name)
            .map(|f| f.frame)
            .collect()
    };
    assert_eq!(frames_of("e2"), vec![10]);
    assert!(
        frames_of("e1").is_empty(),
        "e1 fired at {:?}",
        frames_of("e1")
    );
    assert_eq!(q.status("e1"), Some(EventStatus::Withdrawn));
    assert_eq!(frames_of("e4"), vec![30]);
    assert_eq!(frames_of("spin"), vec![6]);
    assert_eq!(frames_of("topple"), vec![6]);
    assert_eq!(q.status("spin"), Some(EventStatus::Done));
    assert_eq!(frames_of("tick"), (2..40).collect::<Vec<_>>());
    assert!(frames_of("alarm").is_empty());
    assert_eq!(q.status("alarm"), Some(EventStatus::Withdrawn));
    assert_eq!(q.pending(), vec!["tick"]);
}

/// Thesis fig 4.27: small / medium / large impact force → land / bounce / break through.
#[test]
fn branch_selects_by_impact_force() {
    let toml = r#"
[[event]]
name = "hit_floor"
body = "ball"
on = { collision = "floor" }
loop = true
branch.by = "impact_force"
branch.case = [
  { below = 50.0, procedure = "settle" },
  { below = 500.0, procedure = { switch_feature = "bounce" } },
  { procedure = [{ change_material = "shards" }, "unpin"] },
]
"#;
    let mut q = EventQueue::from_toml(toml).unwrap();
    let cases = [
        (1u64, 10.0, vec![Procedure::Settle]),
        (2, 49.999, vec![Procedure::Settle]),
        (
            3,
            50.0,
            vec![Procedure::SwitchFeature(MotionFeature::Bounce)],
        ),
        (
            4,
            200.0,
            vec![Procedure::SwitchFeature(MotionFeature::Bounce)],
        ),
        (
            5,
            500.0,
            vec![Procedure::ChangeMaterial("shards".into()), Procedure::Unpin],
        ),
        (
            6,
            9000.0,
            vec![Procedure::ChangeMaterial("shards".into()), Procedure::Unpin],
        ),
    ];
    for (frame, force, expected) in cases {
        let out =
            q.observe(&Observation::frame(frame, FPS).with_collision("ball", "floor", 3.0, force));
        let procs: Vec<_> = out.iter().map(|f| f.procedure.clone()).collect();
        assert_eq!(procs, expected, "force {force}");
        assert!(out
            .iter()
            .all(|f| f.frame == frame && f.event == "hit_floor"));
    }
    // A collision with something else does not trigger it.
    assert!(q
        .observe(&Observation::frame(7, FPS).with_collision("ball", "wall", 3.0, 10.0))
        .is_empty());

    // By impact speed, with no "otherwise" case: too fast → no case holds → not fired, still
    // queued, and it fires later when a case holds.
    let mut q = EventQueue::new(vec![EventSpec::new(
        "soft_landing",
        "ball",
        Trigger::Collision(None),
    )
    .branch(BranchBy::ImpactSpeed, vec![(Some(2.0), Procedure::Pin)])])
    .unwrap();
    assert!(q
        .observe(&Observation::frame(1, FPS).with_collision("ball", "floor", 5.0, 1.0))
        .is_empty());
    assert_eq!(q.status("soft_landing"), Some(EventStatus::Queued));
    let out = q.observe(&Observation::frame(2, FPS).with_collision("ball", "floor", 1.0, 1e6));
    assert_eq!(fired(&out), vec![(2, "ball", "soft_landing")]);
    assert_eq!(q.status("soft_landing"), Some(EventStatus::Done));
}

/// Time events fire at the first frame whose time reaches them (24 fps: 0.5 s is frame 12,
/// 0.51 s is frame 13, 1/3 s is frame 8 despite 8/24 rounding); frame events at their frame.
#[test]
fn time_and_frame_events_fire_at_the_right_frame() {
    let mut q = EventQueue::new(vec![
        EventSpec::new("t0", "ball", Trigger::Time(0.0))
            .procedure(Procedure::SetVelocity([1.0, 2.0, 3.0])),
        EventSpec::new("t_half", "ball", Trigger::Time(0.5)).procedure(Procedure::Pin),
        EventSpec::new("t_051", "ball", Trigger::Time(0.51)).procedure(Procedure::Unpin),
        EventSpec::new("t_third", "ball", Trigger::Time(1.0 / 3.0))
            .procedure(Procedure::FollowTrajectory("arc".into())),
        EventSpec::new("f7", "cube", Trigger::Frame(7)).procedure(Procedure::Settle),
        EventSpec::new("f100", "cube", Trigger::Frame(100)).procedure(Procedure::Settle),
    ])
    .unwrap();
    let out = run(&mut q, 48, |f| Observation::frame(f, FPS));
    assert_eq!(
        fired(&out),
        vec![
            (0, "ball", "t0"),
            (7, "cube", "f7"),
            (8, "ball", "t_third"),
            (12, "ball", "t_half"),
            (13, "ball", "t_051"),
        ]
    );
    assert_eq!(q.pending(), vec!["f100"]);
    // A driver that accumulates its time step: after 6 steps of 1/24 s the clock reads
    // 0.24999999999999997, and the 0.25 s event must still fire at frame 6, not 7.
    let mut q = EventQueue::new(vec![
        EventSpec::new("quarter", "b", Trigger::Time(0.25)).procedure(Procedure::Pin)
    ])
    .unwrap();
    let mut t = 0.0;
    let mut out = Vec::new();
    for frame in 0..10u64 {
        out.extend(q.observe(&Observation {
            frame,
            time_secs: t,
            ..Observation::default()
        }));
        t += 1.0 / 24.0;
    }
    assert_eq!(fired(&out), vec![(6, "b", "quarter")]);
    // A skipped frame does not lose an event: it fires at the next observation.
    let mut q = EventQueue::new(vec![
        EventSpec::new("f5", "b", Trigger::Frame(5)).procedure(Procedure::Pin)
    ])
    .unwrap();
    assert!(q.observe(&Observation::frame(4, FPS)).is_empty());
    assert_eq!(
        fired(&q.observe(&Observation::frame(6, FPS))),
        vec![(6, "b", "f5")]
    );
}

/// The bounce feature ends when the rebound speed falls under the bound (thesis §4.4.1: "the
/// vertical speed after a rebound within a range"). Rebounds of a ball losing 40 % of its speed
/// per bounce: 4, 2.4, 1.44, 0.864, 0.518, 0.311 m/s; bound 0.4 m/s → the sixth rebound.
#[test]
fn convergence_after_rebounds_fall_under_the_bound() {
    let mut q = EventQueue::from_toml(
        r#"
[[event]]
name = "settled"
body = "ball"
on = { convergence = 0.4 }
procedure = [{ switch_feature = "roll" }, "settle"]

[[event]]
name = "other_ball_settled"
body = "ball2"
on = { convergence = 0.4 }
procedure = "settle"
"#,
    )
    .unwrap();
    let mut speed = 4.0;
    let mut rebound_frames = Vec::new();
    let mut out = Vec::new();
    for frame in 0..100u64 {
        let mut o = Observation::frame(frame, FPS);
        if frame % 10 == 5 {
            rebound_frames.push(frame);
            // ball2 rebounds fast all along and never converges.
            o = o.with_rebound("ball", speed).with_rebound("ball2", 3.0);
            speed *= 0.6;
        }
        out.extend(q.observe(&o));
    }
    assert_eq!(
        fired(&out),
        vec![(55, "ball", "settled"), (55, "ball", "settled")]
    );
    assert_eq!(rebound_frames[5], 55);
    assert_eq!(
        out[0].procedure,
        Procedure::SwitchFeature(MotionFeature::Roll)
    );
    assert_eq!(out[1].procedure, Procedure::Settle);
    assert_eq!(q.status("other_ball_settled"), Some(EventStatus::Queued));
}

/// Thesis fig 4.20 / 4.28: the bowling ball. Throw at t = 0, bounce on the lane only after the
/// throw, roll once converged, collide with pins (loop). Serialised firings use the report
/// format.
#[test]
fn bowling_example_from_the_module_doc() {
    let doc = r#"
[[event]]
name = "throw"
body = "ball"
on = { time = 0.0 }
procedure = [{ switch_feature = "throw" }, { set_velocity = [0.0, 0.0, -8.0] }]

[[event]]
name = "hit_lane"
body = "ball"
on = { collision = "lane" }
after = "throw"
branch.by = "impact_force"
branch.case = [
  { below = 50.0, procedure = "settle" },
  { below = 500.0, procedure = { switch_feature = "bounce" } },
  { procedure = { change_material = "shards" } },
]

[[event]]
name = "settled"
body = "ball"
on = { convergence = 0.2 }
procedure = { switch_feature = "roll" }

[[event]]
name = "hit_pin"
body = "ball"
on = { collision = "pin" }
loop = true
procedure = { switch_feature = "collide" }
"#;
    // The test's text is the module doc's example, verbatim.
    let module = include_str!("../src/events.rs");
    let start = module.find("//! ```toml\n").unwrap() + "//! ```toml\n".len();
    let end = start + module[start..].find("//! ```").unwrap();
    let from_doc: String = module[start..end]
        .lines()
        .map(|l| format!("{}\n", l.trim_start_matches("//!").trim_start_matches(' ')))
        .collect();
    assert_eq!(
        EventQueue::from_toml(&from_doc).unwrap().events(),
        EventQueue::from_toml(doc).unwrap().events()
    );
    let mut q = EventQueue::from_toml(doc).unwrap();
    // Frame 0: the ball already touches the lane, but hit_lane waits for the throw.
    let out = q.observe(&Observation::frame(0, FPS).with_collision("ball", "lane", 0.1, 1.0));
    assert_eq!(
        fired(&out),
        vec![(0, "ball", "throw"), (0, "ball", "throw")]
    );
    assert_eq!(q.status("hit_lane"), Some(EventStatus::Queued));
    let out = q.observe(&Observation::frame(6, FPS).with_collision("ball", "lane", 2.0, 120.0));
    assert_eq!(fired(&out), vec![(6, "ball", "hit_lane")]);
    let out = q.observe(&Observation::frame(20, FPS).with_rebound("ball", 0.1));
    assert_eq!(fired(&out), vec![(20, "ball", "settled")]);
    let out = q.observe(
        &Observation::frame(40, FPS)
            .with_collision("ball", "pin", 7.0, 300.0)
            .with_collision("ball", "lane", 0.0, 5.0),
    );
    assert_eq!(fired(&out), vec![(40, "ball", "hit_pin")]);
    let json = serde_json::to_value(&out[0]).unwrap();
    assert_eq!(
        json,
        serde_json::json!({
            "frame": 40, "body": "ball", "event": "hit_pin",
            "procedure": { "switch_feature": "collide" }
        })
    );
    let unit = Firing {
        frame: 3,
        body: "b".into(),
        event: "e".into(),
        procedure: Procedure::Settle,
    };
    assert_eq!(
        serde_json::to_string(&unit).unwrap(),
        r#"{"frame":3,"body":"b","event":"e","procedure":"settle"}"#
    );
    assert_eq!(q.pending(), vec!["hit_pin"]);

    // The parsed events round-trip through TOML.
    let file = EventsFile {
        event: q.events().to_vec(),
    };
    let text = toml::to_string(&file).unwrap();
    let again = EventQueue::from_toml(&text).unwrap();
    assert_eq!(again.events(), q.events(), "{text}");
}

/// `after` withdrawn with its predecessor; a chain is armed one observation at a time.
#[test]
fn after_chains() {
    let mut q = EventQueue::new(vec![
        EventSpec::new("a", "x", Trigger::Frame(1))
            .procedure(Procedure::Pin)
            .group("g"),
        EventSpec::new("b", "x", Trigger::Frame(0))
            .procedure(Procedure::Unpin)
            .group("g"),
        EventSpec::new("after_a", "x", Trigger::Frame(0))
            .procedure(Procedure::Settle)
            .after("a"),
        EventSpec::new("after_after_a", "x", Trigger::Frame(0))
            .procedure(Procedure::Settle)
            .after("after_a"),
        EventSpec::new("after_b", "x", Trigger::Frame(0))
            .procedure(Procedure::Settle)
            .after("b"),
        EventSpec::new("after_after_b", "x", Trigger::Frame(0))
            .procedure(Procedure::Settle)
            .after("after_b"),
    ])
    .unwrap();
    let out = run(&mut q, 5, |f| Observation::frame(f, FPS));
    assert_eq!(
        fired(&out),
        vec![
            (0, "x", "b"),
            (1, "x", "after_b"),
            (2, "x", "after_after_b")
        ]
    );
    for n in ["a", "after_a", "after_after_a"] {
        assert_eq!(q.status(n), Some(EventStatus::Withdrawn), "{n}");
    }
}

/// Bad descriptions are typed errors that say where; nothing panics.
#[test]
fn invalid_descriptions_are_reported_with_location() {
    let err = |text: &str| EventQueue::from_toml(text).unwrap_err();
    let head = "[[event]]\nname = \"e\"\nbody = \"b\"\n";

    let e = err(&format!(
        "{head}on = {{ frame = 1 }}\nprocedure = \"pinn\"\n"
    ));
    assert_eq!(e.line, Some(5), "{e}");
    assert!(e.message.contains("pinn"), "{e}");

    let e = err(&format!(
        "{head}on = {{ frame = 1 }}\nprocedure = \"pin\"\nlop = true\n"
    ));
    assert_eq!(e.line, Some(6), "{e}");
    assert!(
        e.message.contains("lop") && e.message.contains("loop"),
        "{e}"
    );

    let e = err(&format!(
        "{head}on = {{ clock = 1 }}\nprocedure = \"pin\"\n"
    ));
    assert!(e.message.contains("clock"), "{e}");

    let e = err(&format!("{head}on = {{ frame = 1 }}\n"));
    assert!(e.to_string().contains("needs a `procedure`"), "{e}");

    let e = err(&format!(
        "{head}on = {{ time = -1.0 }}\nprocedure = \"pin\"\n"
    ));
    assert_eq!(e.location, "event[0] \"e\".on.time", "{e}");

    let e = err(&format!(
        "{head}on = {{ convergence = 0.0 }}\nprocedure = \"pin\"\n"
    ));
    assert_eq!(e.location, "event[0] \"e\".on.convergence", "{e}");

    let e = err(&format!(
        "{head}on = {{ frame = 1 }}\nbranch.by = \"impact_force\"\nbranch.case = [{{ procedure = \"pin\" }}]\n"
    ));
    assert_eq!(e.location, "event[0] \"e\".branch.by", "{e}");

    let e = err(&format!(
        "{head}on = {{ collision = \"*\" }}\nbranch.by = \"impact_force\"\nbranch.case = [{{ below = 5.0, procedure = \"pin\" }}, {{ below = 5.0, procedure = \"unpin\" }}]\n"
    ));
    assert_eq!(e.location, "event[0] \"e\".branch.case[1].below", "{e}");

    let e = err(&format!(
        "{head}on = {{ collision = \"*\" }}\nbranch.by = \"impact_force\"\nbranch.case = [{{ procedure = \"pin\" }}, {{ below = 5.0, procedure = \"unpin\" }}]\n"
    ));
    assert_eq!(e.location, "event[0] \"e\".branch.case[0].below", "{e}");

    let e = err(&format!(
        "{head}on = {{ frame = 1 }}\nprocedure = {{ apply_force = {{ force_n = [0, 1, 0], duration_secs = 0 }} }}\n"
    ));
    assert_eq!(e.location, "event[0] \"e\".procedure[0]", "{e}");

    let e = err(&format!(
        "{head}on = {{ frame = 1 }}\nprocedure = \"pin\"\n{head}on = {{ frame = 2 }}\nprocedure = \"pin\"\n"
    ));
    assert_eq!(e.location, "event[1].name", "{e}");

    let e = err(&format!(
        "{head}on = {{ frame = 1 }}\nprocedure = \"pin\"\nafter = \"nobody\"\n"
    ));
    assert!(e.message.contains("nobody"), "{e}");

    let cycle = vec![
        EventSpec::new("p", "b", Trigger::Frame(0))
            .procedure(Procedure::Pin)
            .after("q"),
        EventSpec::new("q", "b", Trigger::Frame(0))
            .procedure(Procedure::Pin)
            .after("p"),
    ];
    assert!(EventQueue::new(cycle)
        .unwrap_err()
        .message
        .contains("loops"));

    let nan = vec![EventSpec::new("n", "b", Trigger::Frame(0))
        .procedure(Procedure::SetVelocity([0.0, f64::NAN, 0.0]))];
    assert!(EventQueue::new(nan).is_err());

    // NaN observations are not an error: they match no threshold (the "otherwise" case does).
    let mut q = EventQueue::new(vec![EventSpec::new("h", "b", Trigger::Collision(None))
        .branch(
            BranchBy::ImpactForce,
            vec![(Some(1.0), Procedure::Pin), (None, Procedure::Unpin)],
        )])
    .unwrap();
    let out = q.observe(&Observation::frame(0, FPS).with_collision("b", "c", f64::NAN, f64::NAN));
    assert_eq!(out[0].procedure, Procedure::Unpin);
}
