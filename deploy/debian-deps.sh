# Sourced by the setup scripts: installs Debian 12 packages that are missing, idempotently.
# Usage: gvd_install_packages GROUP...   (groups: build, test)

GVD_PACKAGES_build="cmake ninja-build g++ pkgconf ccache
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler libabsl-dev libboost-dev
  libsqlite3-dev prometheus-cpp-dev
  libegl-dev libopengl-dev libegl1 libopengl0 libegl-mesa0 libgl1-mesa-dri"
GVD_PACKAGES_test="libgtest-dev libgmock-dev libbenchmark-dev libnanoflann-dev openssl"

gvd_install_packages() {
  local wanted="" group pkg missing=""
  for group in "$@"; do
    eval "wanted=\"\$wanted \$GVD_PACKAGES_$group\""
  done
  for pkg in $wanted; do
    if [ "$(dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null)" != "install ok installed" ]; then
      missing="$missing $pkg"
    fi
  done
  [ -z "$missing" ] && return 0
  local sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  echo "Installing:$missing"
  $sudo apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends $missing
}
