#!/usr/bin/env bash
# A throwaway PostgreSQL cluster that speaks TLS only, for tests/api/pg_tls.rs.
#
#   eval "$(.ci/pg_tls.sh)"   # start (or reuse) it; sets TRUECUT_TEST_PG_TLS,
#                             # TRUECUT_TEST_PG_TLS_ROOT and TRUECUT_TEST_PG_TLS_WRONG_ROOT
#   .ci/pg_tls.sh stop        # stop it and remove its directory
#
# The cluster lives in $TRUECUT_PG_TLS_DIR (default /tmp/truecut-pg-tls) and listens on
# 127.0.0.1:$TRUECUT_PG_TLS_PORT (default 5433), beside the main cluster on 5432, and on
# 127.0.0.2 (an address its certificate does not list, for the host-name check). Its
# pg_hba.conf has `hostssl` lines only, so a plain TCP connection is refused; the server
# certificate (CN localhost, SAN localhost and 127.0.0.1) is signed by a test CA made here,
# and a second, unrelated CA ("wrong" root) lets tests check that verification refuses.
# Trust authentication: nothing here is a secret, and everything goes with `stop`.
# Only `export` lines go to stdout; progress goes to stderr.
set -euo pipefail

dir="${TRUECUT_PG_TLS_DIR:-/tmp/truecut-pg-tls}"
port="${TRUECUT_PG_TLS_PORT:-5433}"
data="${dir}/data"

say() { echo "pg_tls: $*" >&2; }

bin_dir() {
  local d
  d="$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1 || true)"
  if [[ -z "${d}" || ! -x "${d}/initdb" ]]; then
    say "no initdb under /usr/lib/postgresql/*/bin (apt-get install postgresql)"
    exit 1
  fi
  echo "${d}"
}

# Runs a PostgreSQL program as the postgres user when we are root (initdb and the server
# refuse to run as root), as ourselves otherwise.
as_pg() {
  if [[ "$(id -u)" == 0 ]]; then
    runuser -u postgres -- "$@"
  else
    "$@"
  fi
}

running() {
  [[ -f "${data}/postmaster.pid" ]] && as_pg "${bin}/pg_ctl" -D "${data}" status >/dev/null 2>&1
}

stop() {
  if [[ -d "${data}" ]] && running; then
    as_pg "${bin}/pg_ctl" -D "${data}" -m fast -w stop >&2
  fi
  rm -rf "${dir}"
  say "stopped and removed ${dir}"
}

# A CA (key + self-signed certificate) named $2 in files $1.key, $1.crt.
make_ca() {
  openssl req -x509 -new -nodes -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 \
    -keyout "$1.key" -out "$1.crt" -days 30 -subj "/CN=$2" \
    -addext "basicConstraints=critical,CA:TRUE" \
    -addext "keyUsage=critical,keyCertSign,cRLSign" 2>/dev/null
}

make_certs() {
  local tls="${dir}/tls"
  mkdir -p "${tls}"
  make_ca "${tls}/ca" "truecut test CA"
  make_ca "${tls}/wrong-ca" "truecut unrelated CA"
  openssl req -new -nodes -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 \
    -keyout "${tls}/server.key" -out "${tls}/server.csr" -subj "/CN=localhost" 2>/dev/null
  printf '%s\n' \
    "basicConstraints=critical,CA:FALSE" \
    "keyUsage=critical,digitalSignature,keyEncipherment" \
    "extendedKeyUsage=serverAuth" \
    "subjectAltName=DNS:localhost,IP:127.0.0.1" >"${tls}/server.ext"
  openssl x509 -req -in "${tls}/server.csr" -CA "${tls}/ca.crt" -CAkey "${tls}/ca.key" \
    -CAcreateserial -out "${tls}/server.crt" -days 30 -extfile "${tls}/server.ext" 2>/dev/null
  # The server reads its key only if no one else may (0600, its own user).
  cp "${tls}/server.crt" "${tls}/server.key" "${data}/"
  chmod 0600 "${data}/server.key"
  chmod 0644 "${tls}"/*.crt
}

start() {
  if [[ -d "${data}" ]] && running; then
    say "reusing the cluster already running in ${data}"
    return
  fi
  if [[ -d "${data}" && -f "${data}/server.crt" && -f "${dir}/tls/ca.crt" ]]; then
    say "restarting the cluster in ${data}"
  else
    rm -rf "${dir}"
    mkdir -p "${data}"
    if [[ "$(id -u)" == 0 ]]; then chown postgres: "${dir}" "${data}"; fi
    chmod 0755 "${dir}"
    chmod 0700 "${data}"
    as_pg "${bin}/initdb" -D "${data}" -U postgres -A trust --no-sync >/dev/null
    make_certs
    if [[ "$(id -u)" == 0 ]]; then chown postgres: "${data}/server.crt" "${data}/server.key"; fi
    cat >>"${data}/postgresql.conf" <<EOF
# truecut .ci/pg_tls.sh
listen_addresses = '127.0.0.1,127.0.0.2'
port = ${port}
unix_socket_directories = '${dir}'
ssl = on
ssl_cert_file = 'server.crt'
ssl_key_file = 'server.key'
fsync = off
EOF
    # TCP only over TLS: no `host` line, so a plain connection finds no entry.
    cat >"${data}/pg_hba.conf" <<EOF
local   all all                trust
hostssl all all 127.0.0.0/8    trust
EOF
  fi
  if (exec 3<>"/dev/tcp/127.0.0.1/${port}") 2>/dev/null; then
    say "port ${port} is taken by another server (set TRUECUT_PG_TLS_PORT)"
    exit 1
  fi
  as_pg "${bin}/pg_ctl" -D "${data}" -l "${dir}/server.log" -w -t 30 start >/dev/null \
    || { cat "${dir}/server.log" >&2; exit 1; }
  if ! as_pg "${bin}/psql" -h "${dir}" -p "${port}" -U postgres -d postgres -tAq \
      -c "SELECT 1 FROM pg_database WHERE datname = 'test'" | grep -q 1; then
    as_pg "${bin}/createdb" -h "${dir}" -p "${port}" -U postgres test
  fi
  say "TLS-only PostgreSQL on 127.0.0.1:${port} (${dir})"
}

bin="$(bin_dir)"
case "${1:-start}" in
  start)
    start
    root="${dir}/tls/ca.crt"
    echo "export TRUECUT_TEST_PG_TLS='postgres://postgres@127.0.0.1:${port}/test?sslmode=verify-full&sslrootcert=${root}'"
    echo "export TRUECUT_TEST_PG_TLS_ROOT='${root}'"
    echo "export TRUECUT_TEST_PG_TLS_WRONG_ROOT='${dir}/tls/wrong-ca.crt'"
    ;;
  stop) stop ;;
  *)
    say "usage: $0 [start|stop]"
    exit 2
    ;;
esac
