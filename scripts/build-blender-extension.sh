#!/usr/bin/env bash
# Builds the Blender extension zip (install in Blender: Edit → Preferences → Get Extensions →
# ⌄ → Install from Disk). Usage: scripts/build-blender-extension.sh [OUT.zip]
# Default output: target/blender/springbake-<version>.zip. Prints the zip's path.
set -euo pipefail
cd "$(dirname "$0")/.."
src=blender/springbake
version=$(sed -n 's/^version = "\(.*\)"/\1/p' "$src/blender_manifest.toml")
out=${1:-target/blender/springbake-$version.zip}
mkdir -p "$(dirname "$out")"
python3 - "$src" "$out" <<'PY'
import os, sys, zipfile
src, out = sys.argv[1], sys.argv[2]
tmp = out + ".tmp"
with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
    for name in sorted(os.listdir(src)):
        if name.endswith((".py", ".toml")):
            # Fixed timestamps: the same sources give the same zip bytes.
            info = zipfile.ZipInfo(name, date_time=(2024, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            with open(os.path.join(src, name), "rb") as f:
                z.writestr(info, f.read())
os.replace(tmp, out)
PY
echo "$out"
