# shellcheck shell=bash
# Sourced by the shell tests that start a gvd-server of their own: a scratch folder $work,
# removed at exit with the server stopped.
# gvd_server_start BINARY [FLAGS...]: starts BINARY on a loopback port with its store in
# $work/data and its log in $work/log, waits for its port and sets $port and $gvd_server_pid;
# fails, printing the log, where it writes no port within 30 s.
work=$(mktemp -d)
gvd_server_pid=""
gvd_server_cleanup() {
  if [[ -n $gvd_server_pid ]]; then
    kill "$gvd_server_pid" 2>/dev/null && wait "$gvd_server_pid" 2>/dev/null
  fi
  rm -rf "$work"
}
trap gvd_server_cleanup EXIT
gvd_server_start() {
  local binary=$1
  shift
  "$binary" --listen 127.0.0.1:0 --port-file "$work/port" --data "$work/data" "$@" 2>"$work/log" &
  gvd_server_pid=$!
  for _ in $(seq 600); do [[ -s $work/port ]] && break; sleep 0.05; done
  if [[ ! -s $work/port ]]; then
    echo "FAIL: $binary wrote no port:"
    cat "$work/log"
    exit 1
  fi
  # shellcheck disable=SC2034  # read by the test that sources this
  port=$(head -1 "$work/port")
}
