//! AFL entry for the `usd_mesh` fuzz target (`springbake_fuzz::usd_mesh`).
fn main() {
    afl::fuzz!(|data: &[u8]| springbake_fuzz::usd_mesh(data));
}
