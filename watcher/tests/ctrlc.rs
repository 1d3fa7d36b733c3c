//! `install_ctrlc` in its own test binary (the handler is process-wide): a real SIGINT sent to
//! this process sets the stop token, and a second installation is refused.

#![cfg(unix)]

use springbake_watcher::{install_ctrlc, CancelToken, WatchError};
use std::time::{Duration, Instant};

#[test]
fn sigint_sets_the_stop_token() {
    let stop = CancelToken::new();
    install_ctrlc(stop.clone()).unwrap();
    assert!(matches!(
        install_ctrlc(CancelToken::new()),
        Err(WatchError::Signal(_))
    ));
    assert!(!stop.is_cancelled());
    let status = std::process::Command::new("kill")
        .args(["-INT", &std::process::id().to_string()])
        .status()
        .expect("the `kill` command is needed to send SIGINT");
    assert!(status.success());
    let start = Instant::now();
    while !stop.is_cancelled() {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "SIGINT did not set the token"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}
