# shellcheck shell=bash
# Sourced by the setup scripts: installs Debian 12 packages that are missing, idempotently.
# Usage: gvd_install_packages GROUP...   (groups: build, test, node, bench)

gvd_packages() {
  case "$1" in
    build)
      echo cmake ninja-build g++ pkgconf ccache \
        libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler libabsl-dev \
        libboost-dev libssl-dev libglm-dev libsqlite3-dev prometheus-cpp-dev libopenimageio-dev \
        libegl-dev libopengl-dev libegl1 libopengl0 libegl-mesa0 libgl1-mesa-dri libassimp-dev \
        libopenvdb-dev libboost-iostreams-dev libpq-dev zlib1g-dev rapidjson-dev \
        libgoogle-perftools-dev
      ;;
    test)
      echo libgtest-dev libgmock-dev libbenchmark-dev libnanoflann-dev libqhull-dev openssl curl \
        shellcheck yamllint python3-yaml chromium chromium-driver python3-selenium \
        python3-openvdb postgresql iproute2 \
        python3-venv python3-setuptools python3-wheel python3-pytest python3-grpcio \
        python3-protobuf python3-numpy python3-httptools \
        libfreetype-dev fonts-dejavu-core fonts-cantarell assimp-testmodels \
        python3-svgelements python3-defusedxml libwacom-common gdal-data \
        libpng-dev libjpeg-dev libopenexr-dev
      ;;
    node)  # the TypeScript client's tests (client/ts), where no Node.js is installed
      echo nodejs npm
      ;;
    bench)  # the reference libraries of tests/bench/run.sh beyond the test group's, the
      # stock Python gRPC client of tests/bench/serve.py, and the load generators and
      # instruction counter of tests/bench/transports.sh, PostGIS and psycopg2 for
      # tests/bench/postgis.py
      echo libopencv-dev python3-opencv python3-scipy python3-numpy python3-grpcio libembree-dev \
        python3-protobuf wrk nghttp2-client valgrind postgresql-15-postgis-3 python3-psycopg2
      ;;
    *)
      echo "gvd_packages: unknown group $1" >&2
      return 1
      ;;
  esac
}

gvd_install_packages() {
  local group pkg
  local -a wanted=() missing=() sudo=()
  for group in "$@"; do
    read -r -a pkgs <<<"$(gvd_packages "$group")"
    wanted+=("${pkgs[@]}")
  done
  for pkg in "${wanted[@]}"; do
    if [ "$(dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null)" != "install ok installed" ]; then
      missing+=("$pkg")
    fi
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  [ "$(id -u)" -ne 0 ] && sudo=(sudo)
  echo "Installing: ${missing[*]}"
  "${sudo[@]}" apt-get update -q
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
    "${missing[@]}"
}
