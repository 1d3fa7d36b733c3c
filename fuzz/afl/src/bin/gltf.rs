//! AFL entry for the `gltf` fuzz target (`springbake_fuzz::gltf`).
fn main() {
    afl::fuzz!(|data: &[u8]| springbake_fuzz::gltf(data));
}
