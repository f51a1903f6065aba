#!/usr/bin/env bash
# Runs gvd-server (GVD_SERVER) with the rest of its arguments, in a private mount namespace
# where GVD_SMALL_DISK_DIR is a tmpfs of GVD_SMALL_DISK_SIZE: a small disk of its own to put
# the store on (unshare -rm needs no privileges where user namespaces are allowed). While the
# server runs, creating the file $GVD_SMALL_DISK_CONTROL/fill fills what is left of that disk
# and $GVD_SMALL_DISK_CONTROL/free frees it; each is answered by a file "filled" or "freed"
# there. The server keeps this script's process id, so signals reach it.
set -euo pipefail
# shellcheck disable=SC2016  # the inner script expands its variables itself
exec unshare -rm sh -c '
  mount -t tmpfs -o size="$GVD_SMALL_DISK_SIZE" gvd-small-disk "$GVD_SMALL_DISK_DIR" || exit 97
  server=$$
  (
    while kill -0 "$server" 2>/dev/null; do
      if [ -e "$GVD_SMALL_DISK_CONTROL/fill" ]; then
        rm -f "$GVD_SMALL_DISK_CONTROL/fill"
        dd if=/dev/zero of="$GVD_SMALL_DISK_DIR/filler" bs=4k 2>/dev/null || true
        touch "$GVD_SMALL_DISK_CONTROL/filled"
      fi
      if [ -e "$GVD_SMALL_DISK_CONTROL/free" ]; then
        rm -f "$GVD_SMALL_DISK_CONTROL/free" "$GVD_SMALL_DISK_DIR/filler"
        touch "$GVD_SMALL_DISK_CONTROL/freed"
      fi
      sleep 0.05
    done
  ) &
  exec "$GVD_SERVER" "$@"
' gvd-small-disk "$@"
