#!/bin/bash
# Starts PostgreSQL for the fleet (compose.yaml, service db: its entrypoint), in front of the
# postgres image's own entrypoint.
#
# It waits (up to 60 s) for the secrets the `secrets` service makes on the first start:
# docker compose starts db only after that service ended (service_completed_successfully),
# but podman-compose 1.0.3 ignores depends_on conditions and starts both at once.
# The password of the superuser comes from POSTGRES_PASSWORD_FILE, which the official
# image's entrypoint reads itself; an entrypoint that does not know the _FILE variables
# (the Debian-based stand-in that ../shared/tools/compose-check builds) is given it as
# POSTGRES_PASSWORD instead, in this process's environment only.
set -euo pipefail

for file in "${POSTGRES_PASSWORD_FILE:?}" "${TRUECUT_DB_PASSWORD_FILE:?}"; do
    for _ in $(seq 1 60); do
        [ -s "$file" ] && break
        echo "db-start: waiting for $file (made by the secrets service)"
        sleep 1
    done
    [ -s "$file" ] || { echo "db-start: $file is missing: did the secrets service run?" >&2; exit 1; }
done

entrypoint=$(command -v docker-entrypoint.sh)
# the official entrypoint reads NAME_FILE variables with its function file_env
if ! grep -q 'file_env' "$entrypoint"; then
    POSTGRES_PASSWORD=$(cat "$POSTGRES_PASSWORD_FILE")
    export POSTGRES_PASSWORD
    unset POSTGRES_PASSWORD_FILE
fi
exec "$entrypoint" "$@"
