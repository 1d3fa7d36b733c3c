//! Runs one input through one fuzz target, to reproduce a finding with a backtrace:
//! `cargo run --release -p springbake-fuzz --example run_case -- gltf target/fuzz/findings/gltf/id:000000...`
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let [_, target, file] = args.as_slice() else {
        eprintln!("usage: run_case TARGET FILE (targets: gltf obj scene usd_mesh)");
        std::process::exit(2);
    };
    let Some((_, run)) = springbake_fuzz::TARGETS.iter().find(|(n, _)| n == target) else {
        eprintln!("unknown target {target}");
        std::process::exit(2);
    };
    let bytes = std::fs::read(file).expect("read the case");
    let started = std::time::Instant::now();
    run(&bytes);
    println!("{target}: {file}: no panic, {:?}", started.elapsed());
}
