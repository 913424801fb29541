#!/usr/bin/env bash
# Installs the Debian 12 packages genscene needs, skipping those already present (idempotent).
# Runs apt-get as root, or through sudo when not root.
set -euo pipefail

PACKAGES=(
  # toolchain (clang and its sanitizer / libFuzzer runtimes for the sanitizer build and fuzz/)
  cmake ninja-build g++ make pkg-config ccache clang libclang-rt-14-dev
  # the format check of scripts/test.sh
  clang-format
  # core
  libeigen3-dev libtbb-dev libcli11-dev nlohmann-json3-dev libspdlog-dev libfmt-dev
  libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev libopenexr-dev
  # fusion (ORB features and PnP when ICP cannot track a frame from the last pose)
  libopencv-features2d-dev libopencv-calib3d-dev
  # fusion's pose graph
  libceres-dev
  libopenmesh-dev
  # inverse (path tracer, Mitsuba XML scenes)
  libembree-dev libtinyxml2-dev
  # capture (OpenNI2 cameras and .oni recordings; openni2-utils brings NiViewer2)
  libopenni2-dev openni2-utils
  # viewer (GLFW window, OpenGL function loading; Mesa's llvmpipe gives OpenGL 3.3+ core under Xvfb)
  libglfw3-dev libepoxy-dev libgl1-mesa-dri
  # the HTML report: Markdown to HTML (GitHub tables), three.js for its 3D view of the model
  libcmark-gfm-dev libcmark-gfm-extensions-dev libjs-three
  # tests (assimp-utils: `assimp info`, the independent reader of the glTF export test)
  libgtest-dev assimp-utils
  # the HTML report's test: headless Chromium opens report.html and takes a screenshot
  chromium
  # viewer tests and headless screenshots: an X server without a screen
  xvfb xauth
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then
    SUDO="sudo"
  else
    echo "install_deps: error: not root and no sudo; install as root: apt-get install ${missing[*]}" >&2
    exit 1
  fi
fi

echo "install_deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
