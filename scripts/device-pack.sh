#!/usr/bin/env bash
# Packs what a run on the device machine needs (an NVIDIA GPU host lent to some sessions: it
# has no cargo, another Python, and no Vulkan loader; docs/benchmarks/2026-12-04-to-05.md, "twenty-fourth
# session"): builds `gpu_bench`, the GPU agreement tests and the CLI in release here and strips
# them into .devbin/, with libpython and a zip of its standard library (the CLI embeds that
# Python), and fetches the Vulkan loader and glvnd packages into .gl/. Both folders are ignored.
# Then call the device tool's `run` with carry [".gl", ".devbin"] and a command such as
#   bash .devbin/on-device.sh gpu_bench 128 --frames 100 --cpu-max 0 --profile
#   bash .devbin/on-device.sh agreement
#   bash .devbin/on-device.sh springbake bake examples/cube.obj --device gpu -o /tmp/c.pc2
set -euo pipefail
cd "$(dirname "$0")/.."
target=${CARGO_TARGET_DIR:-target}
cargo build --release -p springbake-gpu --example gpu_bench
cargo build --release --bin springbake
agreement=$(cargo test --release -p springbake-gpu --test agreement --no-run --message-format=json |
    python3 -c 'import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("executable"):
        print(m["executable"])')
mkdir -p .devbin .gl
strip -o .devbin/gpu_bench "$target/release/examples/gpu_bench"
strip -o .devbin/springbake "$target/release/springbake"
strip -o .devbin/agreement "$agreement"
libpython=$(ldd "$target/release/springbake" | awk '/libpython/ {print $3}')
cp "$libpython" .devbin/
version=$(basename "$libpython" | sed -E 's/libpython([0-9]+\.[0-9]+).*/\1/')
rm -f ".devbin/python${version/./}.zip"
(cd "/usr/lib/python$version" && zip -qr "$OLDPWD/.devbin/python${version/./}.zip" . \
    -x '*__pycache__*' 'test/*' 'idlelib/*' 'tkinter/*' 'ensurepip/*' 'lib2to3/*' \
    'config-*' 'site-packages/*' 'dist-packages/*')
cp scripts/on-device.sh .devbin/
o=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64-lists)
mkdir -p /tmp/amd64-lists/partial
apt-get "${o[@]}" update -qq
(cd .gl && apt-get "${o[@]}" download -qq libvulkan1 libglvnd0 libegl1 libgl1 libglx0 libopengl0 libgles2)
du -sh .devbin .gl
