#!/bin/bash
# The fleet's secrets (compose.yaml, service `secrets`): made on the first start, kept after.
#
# Runs as root in the postgres image (the one the db service runs, so the `postgres` user has
# the same uid and gid here as there) with two volumes:
#   /run/fleet-secrets/db       the db service's:
#       postgres-password       PostgreSQL's superuser (postgres), for the db service only
#       truecut-password        truecut's database role, read by deploy/initdb/10-truecut-role.sh
#   /run/fleet-secrets/truecut  the truecut instances' (and the migrate step's):
#       db-password             truecut's database role (the same as db/truecut-password)
#       admin-token             the admin token: what an operator sends (README, "A fleet")
#       tokens                  the tokens file truecut reads (TRUECUT_TOKENS_FILE)
# A secret is 32 random bytes from /dev/urandom as 64 hex digits, made only when its file is
# missing or empty: there is no default anyone could know. Each file is readable by the one
# user that needs it (uid 10001 is truecut's, Dockerfile).
#
# `tokens` is written again on every start: the admin token, and an `admin` token for
# ../shared/tools/compose-check (it PUTs a machine, which needs admin) only when TRUECUT_CHECK_TOKEN is set in the environment of
# `up` (compose.yaml passes it; unset, the default, there is none, and a check token of an
# earlier start is dropped).
set -euo pipefail

db_dir=${FLEET_DB_SECRETS:-/run/fleet-secrets/db}
tc_dir=${FLEET_TRUECUT_SECRETS:-/run/fleet-secrets/truecut}
truecut_uid=10001
pg_uid=$(id -u postgres)
pg_gid=$(id -g postgres)
umask 077

# one line (a reader drops the newline: truecut, the postgres entrypoint, psql)
random_secret() { od -An -N32 -tx1 /dev/urandom | tr -d ' \n'; echo; }

# put FILE OWNER:GROUP MODE: content from stdin, replacing FILE atomically
put() {
    cat >"$1.new"
    chown "$2" "$1.new"
    chmod "$3" "$1.new"
    mv -f "$1.new" "$1"
}

# ensure FILE OWNER:GROUP: a fresh secret unless FILE holds one
ensure() {
    if [ -s "$1" ]; then
        echo "fleet-secrets: kept $1"
        chown "$2" "$1"
        chmod 0400 "$1"
    else
        random_secret | put "$1" "$2" 0400
        echo "fleet-secrets: generated $1"
    fi
}

mkdir -p "$db_dir" "$tc_dir"
chmod 0755 "$db_dir" "$tc_dir"

ensure "$db_dir/postgres-password" "$pg_uid:$pg_gid"
ensure "$db_dir/truecut-password" "$pg_uid:$pg_gid"
ensure "$tc_dir/admin-token" "$truecut_uid:$truecut_uid"
# truecut's copy of its database password always equals the one the role was made with
put "$tc_dir/db-password" "$truecut_uid:$truecut_uid" 0400 <"$db_dir/truecut-password"

check_token=${TRUECUT_CHECK_TOKEN:-}
if [ -n "$check_token" ] && ! [[ "$check_token" =~ ^[A-Za-z0-9._~-]{16,}$ ]]; then
    echo "fleet-secrets: TRUECUT_CHECK_TOKEN must be 16 or more of A-Z a-z 0-9 . _ ~ -" >&2
    exit 1
fi
{
    echo "# written by deploy/fleet-secrets.sh at every start: TOKEN ROLE"
    printf '%s admin\n' "$(cat "$tc_dir/admin-token")"
    if [ -n "$check_token" ]; then
        printf '%s admin\n' "$check_token"
    fi
} | put "$tc_dir/tokens" "$truecut_uid:$truecut_uid" 0400
if [ -n "$check_token" ]; then
    echo "fleet-secrets: tokens: the admin token and the check token (TRUECUT_CHECK_TOKEN, role admin)"
else
    echo "fleet-secrets: tokens: the admin token"
fi
