# shellcheck shell=bash
# Sourced by the deployment tests (tests/deploy/*_test.sh) from the checkout's root: finds
# podman, the OCI runtime and the image built from this very source, and checks that the
# runtime can start a container and run a command in it. Where any of these is missing it
# exits 77 (ctest's skip), saying why; it never tests an image built from other source.
#
# Reads: needs_exec (1 where the test needs `podman exec`, as healthchecks do).
# Sets: podman (podman and its storage options), image (the image to test), runtime (the OCI
# runtime for --runtime, or empty for podman's own).
# Environment:
#   GVD_IMAGE        test this image as it is (no source check, no build)
#   GVD_BUILD_IMAGE  1: build the image from deploy/Dockerfile when this source has none
#                    (needs the debian:bookworm base images, see deploy/README.md); the
#                    images built from older source are removed then, as each holds ~1 GB
#   GVD_OCI_RUNTIME  an OCI runtime for podman's --runtime (default: ../shared/tools/runc-norlimits
#                    beside the checkout where it exists, for sandboxes that refuse rlimits;
#                    else podman's own)

skip() { echo "SKIP: $*"; exit 77; }

command -v podman >/dev/null || skip "podman is not installed (Debian: apt-get install podman runc)"
podman=(podman --storage-driver vfs)
runtime=${GVD_OCI_RUNTIME:-}
if [[ -z $runtime && -x ../shared/tools/runc-norlimits ]]; then
  runtime=$(realpath ../shared/tools/runc-norlimits)
fi

if [[ -n ${GVD_IMAGE:-} ]]; then
  image=$GVD_IMAGE
  "${podman[@]}" image exists "$image" || skip "no image $image (GVD_IMAGE)"
else
  # The tag names a digest of the tracked files the Dockerfile's build reads, as they are now
  # (untracked ones that it would copy make the checkout no source of record: a skip).
  git rev-parse --git-dir >/dev/null 2>&1 || skip "not a git checkout: no digest of its source"
  if [[ -n $(git ls-files --others --exclude-standard -- CMakeLists.txt cmake proto render \
      server client deploy) ]]; then
    skip "untracked files where the image's build reads (git status); GVD_IMAGE names an image"
  fi
  source_digest=$(git ls-files -z -- CMakeLists.txt cmake proto render server client deploy \
    | xargs -0 sha256sum | sha256sum | cut -c1-16)
  image=localhost/gvd:src-$source_digest
  if ! "${podman[@]}" image exists "$image"; then
    [[ ${GVD_BUILD_IMAGE:-} == 1 ]] \
      || skip "no image built from this source ($image); GVD_BUILD_IMAGE=1 builds it (deploy/README.md)"
    "${podman[@]}" image exists docker.io/library/debian:bookworm \
      || skip "no debian:bookworm base image to build $image from (deploy/README.md)"
    # No intermediate images: under the vfs driver each is a whole copy of the filesystem.
    "${podman[@]}" build --pull=never --network=host --isolation=chroot --layers=false \
      -f deploy/Dockerfile -t "$image" .
    for old in $("${podman[@]}" images --format '{{.Repository}}:{{.Tag}}' localhost/gvd); do
      [[ $old == "$image" || $old != localhost/gvd:src-* ]] \
        || "${podman[@]}" rmi "$old" >/dev/null 2>&1 || true  # one still in use stays
    done
    "${podman[@]}" image prune -f >/dev/null || true
  fi
fi

# Can this machine's runtime start a container and run a command inside it (what podman's
# healthchecks do)? A refusal here is the machine's, not the image's.
probe=gvd-probe-$$
runtime_args=()
runtime_name="podman's own"
if [[ -n $runtime ]]; then
  runtime_args=(--runtime "$runtime")
  runtime_name=$runtime
fi
if ! probe_error=$("${podman[@]}" "${runtime_args[@]}" run -d --rm --name "$probe" \
    --network=host --entrypoint sleep "$image" 60 2>&1); then
  "${podman[@]}" rm -f -t 0 "$probe" >/dev/null 2>&1 || true
  skip "podman cannot start a container here (runtime $runtime_name: $probe_error);" \
    "set GVD_OCI_RUNTIME"
fi
if [[ ${needs_exec:-} == 1 ]] \
    && ! probe_error=$("${podman[@]}" "${runtime_args[@]}" exec "$probe" true 2>&1); then
  "${podman[@]}" rm -f -t 0 "$probe" >/dev/null 2>&1 || true
  skip "podman cannot run a command in a container here (runtime $runtime_name:" \
    "$probe_error); set GVD_OCI_RUNTIME"
fi
"${podman[@]}" rm -f -t 0 "$probe" >/dev/null 2>&1 || true
