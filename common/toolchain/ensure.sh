#!/usr/bin/env bash
# Make sure the Debian cross toolchain and QEMU that the firmware image and the emulated
# Cortex-M4F board are built and run with are installed (docs/image.md, docs/emulator.md):
#   gcc-arm-none-eabi, libnewlib-arm-none-eabi (C library headers), qemu-system-arm;
# and the host C compiler that builds the native kernels for the desktop (docs/native.md: the
# x64 native module and the CPython extension): gcc.
# Versions are pinned to what the project was built and measured with (Debian 12). When a
# package is missing: as root, apt-get installs the pinned version; otherwise this prints the
# command to run and fails. Nothing is ever skipped: a build that needs the toolchain stops here.
set -euo pipefail

PINNED=(
  "gcc-arm-none-eabi=15:12.2.rel1-1"
  "libnewlib-arm-none-eabi=3.3.0-1.3+deb12u1"
  "qemu-system-arm=1:7.2+dfsg-7+deb12u18+b3"
  "gcc=4:12.2.0-3"
)

have() {  # a package's tool is present: the command, or newlib's header for the C library
  case "$1" in
    gcc-arm-none-eabi) command -v arm-none-eabi-gcc >/dev/null ;;
    libnewlib-arm-none-eabi) [ -f /usr/lib/arm-none-eabi/include/stdlib.h ] ;;
    qemu-system-arm) command -v qemu-system-arm >/dev/null ;;
    gcc) command -v gcc >/dev/null ;;
  esac
}

missing=()
for spec in "${PINNED[@]}"; do
  have "${spec%%=*}" || missing+=("$spec")
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "toolchain: installing ${missing[*]%%=*} (Debian packages, pinned)" >&2
if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null; then
  export DEBIAN_FRONTEND=noninteractive
  if ! apt-get install -y --no-install-recommends "${missing[@]}" >&2; then
    apt-get update >&2 || true
    apt-get install -y --no-install-recommends "${missing[@]}" >&2 || {
      echo "toolchain: apt-get could not install ${missing[*]}" >&2
      echo "  (a newer Debian revision? apt-cache policy ${missing[*]%%=*} lists what is" \
           "available; update the pins in common/toolchain/ensure.sh)" >&2
      exit 1
    }
  fi
  for spec in "${missing[@]}"; do
    have "${spec%%=*}" || { echo "toolchain: ${spec%%=*} installed but not usable" >&2; exit 1; }
  done
  exit 0
fi
echo "toolchain: missing ${missing[*]%%=*}; install them with" >&2
echo "  sudo apt-get install ${missing[*]}" >&2
exit 1
