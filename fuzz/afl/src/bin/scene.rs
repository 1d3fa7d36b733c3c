//! AFL entry for the `scene` fuzz target (`springbake_fuzz::scene`).
fn main() {
    afl::fuzz!(|data: &[u8]| springbake_fuzz::scene(data));
}
