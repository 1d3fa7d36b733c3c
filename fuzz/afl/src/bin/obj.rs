//! AFL entry for the `obj` fuzz target (`springbake_fuzz::obj`).
fn main() {
    afl::fuzz!(|data: &[u8]| springbake_fuzz::obj(data));
}
