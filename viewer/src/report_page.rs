//! The visual bake report (`springbake bake … --report report.html`): one self-contained HTML
//! page (no script, no external file: it opens offline in any browser) with the bake's flipbook
//! as an embedded GIF, SVG plots of the energies, penetration, inverted cells and substeps
//! against time with the events marked, the bodies and timings, and the warnings explained
//! with what to change.

use base64::Engine;
use springbake_core::solver::FrameDiagnostics;
use springbake_pipeline::Report;
use std::fmt::Write;

/// What the page shows besides the report itself.
pub struct PageInput<'a> {
    pub title: &'a str,
    pub outputs: &'a [std::path::PathBuf],
    /// The bake as an animated GIF, when its output could be rendered.
    pub flipbook_gif: Option<&'a [u8]>,
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// One series of a plot.
struct Series<'a> {
    name: &'a str,
    colour: &'a str,
    values: Vec<f64>,
}

const WIDTH: f64 = 640.0;
const HEIGHT: f64 = 180.0;
const MARGIN: f64 = 44.0;

/// An SVG line plot of `series` against `times`, with `events` (times) as vertical marks.
fn plot(title: &str, unit: &str, times: &[f64], series: &[Series], events: &[f64]) -> String {
    let t_max = times.last().copied().unwrap_or(1.0).max(1e-9);
    let finite = series
        .iter()
        .flat_map(|s| s.values.iter().copied())
        .filter(|v| v.is_finite());
    let (lo, hi) = finite.fold((0.0f64, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let span = if hi - lo > 0.0 { hi - lo } else { 1.0 };
    let x = |t: f64| MARGIN + (WIDTH - MARGIN - 8.0) * t / t_max;
    let y = |v: f64| 8.0 + (HEIGHT - 28.0) * (1.0 - (v - lo) / span);
    let mut svg = format!(
        "<figure><figcaption>{}</figcaption><svg viewBox=\"0 0 {WIDTH} {HEIGHT}\" \
         width=\"{WIDTH}\" height=\"{HEIGHT}\" role=\"img\">",
        escape(title)
    );
    let _ = write!(
        svg,
        "<rect x=\"{MARGIN}\" y=\"8\" width=\"{}\" height=\"{}\" class=\"frame\"/>",
        WIDTH - MARGIN - 8.0,
        HEIGHT - 28.0
    );
    for &t in events {
        let _ = write!(
            svg,
            "<line x1=\"{0:.1}\" x2=\"{0:.1}\" y1=\"8\" y2=\"{1:.1}\" class=\"event\"/>",
            x(t),
            HEIGHT - 20.0
        );
    }
    for s in series {
        let points: Vec<String> = times
            .iter()
            .zip(&s.values)
            .filter(|(_, v)| v.is_finite())
            .map(|(t, v)| format!("{:.1},{:.1}", x(*t), y(*v)))
            .collect();
        let _ = write!(
            svg,
            "<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\" points=\"{}\"><title>{}</title></polyline>",
            s.colour,
            points.join(" "),
            escape(s.name)
        );
    }
    let _ = write!(
        svg,
        "<text x=\"2\" y=\"16\">{}</text><text x=\"2\" y=\"{:.0}\">{}</text>\
         <text x=\"{MARGIN}\" y=\"{:.0}\">0 s</text><text x=\"{:.0}\" y=\"{:.0}\" \
         text-anchor=\"end\">{t_max:.2} s</text></svg>",
        escape(&format!("{} {unit}", short(hi))),
        HEIGHT - 22.0,
        escape(&short(lo)),
        HEIGHT - 4.0,
        WIDTH - 8.0,
        HEIGHT - 4.0
    );
    let legend: Vec<String> = series
        .iter()
        .map(|s| {
            format!(
                "<span style=\"color:{}\">■ {}</span>",
                s.colour,
                escape(s.name)
            )
        })
        .collect();
    let _ = write!(
        svg,
        "<div class=\"legend\">{}</div></figure>",
        legend.join(" ")
    );
    svg
}

/// A number for an axis label: three decimals, or an exponent when large or tiny.
fn short(v: f64) -> String {
    if v != 0.0 && (v.abs() >= 1e4 || v.abs() < 1e-2) {
        format!("{v:.2e}")
    } else {
        format!("{v:.3}")
    }
}

fn column(frames: &[FrameDiagnostics], f: impl Fn(&FrameDiagnostics) -> f64) -> Vec<f64> {
    frames.iter().map(f).collect()
}

/// Warnings a user should act on, each with what to change.
fn warnings(report: &Report) -> Vec<String> {
    let mut out = Vec::new();
    let frames = &report.frames;
    if let Some(worst) = frames.iter().max_by_key(|f| f.inverted_cells) {
        if worst.inverted_cells > 0 {
            out.push(format!(
                "Up to {} lattice cells were inverted (frame {}): the body folded through itself \
                 there. Set [solver] substeps above the {} that frame took, soften the impact \
                 (lower speed), or use a stiffer material.",
                worst.inverted_cells, worst.frame, worst.substeps
            ));
        }
    }
    let gains: Vec<&FrameDiagnostics> = frames
        .iter()
        .filter(|f| f.energy_gain.is_some_and(|g| g > 0.0))
        .collect();
    if let Some(first) = gains.first() {
        out.push(format!(
            "The energy rose beyond the work done in {} frame(s), first at frame {}: the motion \
             took energy from nowhere (bodies thrown apart). Try more substeps ([solver] \
             substeps) or more cells, and check that parts do not start inside each other.",
            gains.len(),
            first.frame
        ));
    }
    if let Some(deepest) = frames
        .iter()
        .max_by(|a, b| a.max_penetration.total_cmp(&b.max_penetration))
    {
        let cell = report
            .bodies
            .iter()
            .map(|b| b.cell_size)
            .fold(f64::INFINITY, f64::min);
        if cell.is_finite() && deepest.max_penetration > 0.5 * cell {
            out.push(format!(
                "Surfaces went {:.3} m into the floor or walls (frame {}), over half a cell \
                 ({:.3} m): the impact is too fast for the substeps. Raise [solver] substeps \
                 or lower the speed.",
                deepest.max_penetration, deepest.frame, cell
            ));
        }
    }
    out
}

/// The whole page.
pub fn report_page(report: &Report, input: &PageInput) -> String {
    let frames = &report.frames;
    let times: Vec<f64> = frames.iter().map(|f| f.time).collect();
    let events: Vec<f64> = report
        .events
        .iter()
        .filter_map(|e| e["frame"].as_u64())
        .filter_map(|f| frames.get((f as usize).saturating_sub(1)).map(|d| d.time))
        .collect();
    let mut html = String::from(
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"generator\" content=\"springbake\">",
    );
    let _ = write!(
        html,
        "<title>springbake report: {}</title><style>\
         body{{font-family:system-ui,sans-serif;background:#1e2126;color:#e6e6e6;margin:2em;max-width:960px}}\
         h1,h2{{font-weight:600}} table{{border-collapse:collapse}} td,th{{padding:2px 10px;text-align:left}}\
         th{{color:#aab}} .warn{{background:#4a3020;padding:8px 12px;border-left:4px solid #e08040;margin:6px 0}}\
         .ok{{color:#8c8}} svg{{background:#25292f}} svg text{{fill:#aab;font-size:11px}}\
         .frame{{fill:none;stroke:#445}} .event{{stroke:#c9a227;stroke-dasharray:3 3}}\
         figure{{margin:1em 0}} figcaption{{margin-bottom:4px}} .legend{{font-size:13px}}\
         </style></head><body>",
        escape(input.title)
    );
    let _ = write!(html, "<h1>{}</h1>", escape(input.title));
    let (first, last) = (
        times.first().copied().unwrap_or(0.0),
        times.last().copied().unwrap_or(0.0),
    );
    let _ = write!(
        html,
        "<p>{} frames ({first:.2}–{last:.2} s), {} bod{}; baked in {:.2} s (import {:.2}, fit {:.2}, \
         simulate {:.2}, export {:.2}).</p>",
        frames.len(),
        report.bodies.len(),
        if report.bodies.len() == 1 { "y" } else { "ies" },
        report.seconds.import + report.seconds.fit + report.seconds.simulate + report.seconds.export,
        report.seconds.import,
        report.seconds.fit,
        report.seconds.simulate,
        report.seconds.export
    );
    let outputs: Vec<String> = input
        .outputs
        .iter()
        .map(|p| format!("<code>{}</code>", escape(&p.display().to_string())))
        .collect();
    let _ = write!(html, "<p>Output: {}</p>", outputs.join(", "));
    html.push_str("<h2>Warnings</h2>");
    let warns = warnings(report);
    if warns.is_empty() {
        html.push_str("<p class=\"ok\">None: no inverted cell, no energy from nowhere, no deep penetration.</p>");
    }
    for w in warns {
        let _ = write!(html, "<div class=\"warn\">{}</div>", escape(&w));
    }
    html.push_str("<h2>The bake</h2>");
    match input.flipbook_gif {
        Some(gif) => {
            let data = base64::engine::general_purpose::STANDARD.encode(gif);
            let _ = write!(
                html,
                "<img alt=\"the bake, frame by frame\" src=\"data:image/gif;base64,{data}\">"
            );
        }
        None => html.push_str("<p>No flipbook: only glTF outputs are rendered here.</p>"),
    }
    html.push_str("<h2>Over time</h2><p>Dashed lines: events that fired.</p>");
    let energies = [
        Series {
            name: "kinetic",
            colour: "#e07b48",
            values: column(frames, |f| f.kinetic_energy),
        },
        Series {
            name: "elastic",
            colour: "#6ea0e6",
            values: column(frames, |f| f.elastic_energy),
        },
        Series {
            name: "gravity",
            colour: "#8c8",
            values: column(frames, |f| f.gravity_energy),
        },
    ];
    html.push_str(&plot("Energy", "J", &times, &energies, &events));
    let depth = [Series {
        name: "deepest penetration",
        colour: "#e07b48",
        values: column(frames, |f| f.max_penetration),
    }];
    html.push_str(&plot(
        "Penetration into rigid surfaces",
        "m",
        &times,
        &depth,
        &events,
    ));
    let inverted = [Series {
        name: "inverted cells",
        colour: "#e05050",
        values: column(frames, |f| f.inverted_cells as f64),
    }];
    html.push_str(&plot("Inverted cells", "", &times, &inverted, &events));
    let substeps = [Series {
        name: "substeps",
        colour: "#6ea0e6",
        values: column(frames, |f| f64::from(f.substeps)),
    }];
    html.push_str(&plot("Substeps per frame", "", &times, &substeps, &events));
    html.push_str("<h2>Bodies</h2><table><tr><th>name</th><th>material</th><th>model</th><th>nodes</th><th>cells</th><th>cell (m)</th><th>mass (kg)</th></tr>");
    for b in &report.bodies {
        let _ = write!(
            html,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.4}</td><td>{:.3}</td></tr>",
            escape(&b.name),
            escape(&b.material),
            escape(&b.model),
            b.nodes,
            b.cells,
            b.cell_size,
            b.mass_kg
        );
    }
    html.push_str("</table>");
    if !report.events.is_empty() {
        html.push_str("<h2>Events</h2><table><tr><th>frame</th><th>body</th><th>event</th><th>procedure</th></tr>");
        for e in &report.events {
            let cell = |k: &str| {
                escape(
                    &e[k]
                        .as_str()
                        .map_or_else(|| e[k].to_string(), str::to_owned),
                )
            };
            let _ = write!(
                html,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                cell("frame"),
                cell("body"),
                cell("event"),
                cell("procedure")
            );
        }
        html.push_str("</table>");
    }
    html.push_str("</body></html>\n");
    html
}
