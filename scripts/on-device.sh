#!/usr/bin/env bash
# Runs one of the binaries scripts/device-pack.sh packed, on the device machine: unpacks the
# Vulkan loader and glvnd, points the loader at NVIDIA's driver and the CLI at the packed
# Python, prints the GPU and the host's load, then runs `$1` with the rest of the arguments
# (the agreement tests from gpu/, where they find their fixtures).
set -uo pipefail
cd "$(dirname "$0")/.."
for deb in .gl/*.deb; do dpkg -x "$deb" /; done
ldconfig
B=$PWD/.devbin
export LD_LIBRARY_PATH=$B
for icd in /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json /usr/share/vulkan/icd.d/nvidia_icd.json; do
    if [ -f "$icd" ]; then export VK_DRIVER_FILES=$icd; break; fi
done
zip=$(ls "$B"/python3*.zip | head -1)
mkdir -p /tmp/pyhome/lib && cp "$zip" /tmp/pyhome/lib/ && export PYTHONHOME=/tmp/pyhome
command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
echo "$(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg)"
program=$1
shift
if [ "$program" = agreement ]; then
    cd gpu && exec "$B/agreement" "$@"
fi
exec "$B/$program" "$@"
