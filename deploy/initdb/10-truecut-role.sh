#!/bin/bash
# truecut's own database role and database (compose.yaml, service db; mounted into
# /docker-entrypoint-initdb.d). The postgres image's entrypoint runs this once, on an empty
# data dir, as the postgres user, while the server listens on its Unix socket only; it
# sources the file (so: no `set` options here, they would change its shell).
#
# The role can log in and owns the database `truecut` (and so its public schema, where the
# migrations create the tables), and nothing more: no superuser, no CREATEDB, no CREATEROLE,
# no replication. The superuser (postgres) is for the operator; the instances never use it.
# The password is the one deploy/fleet-secrets.sh generated, read from the file that
# TRUECUT_DB_PASSWORD_FILE names by psql itself (so it is on no command line) and quoted by
# psql (:'password').

: "${TRUECUT_DB_PASSWORD_FILE:?names the file holding truecut role password (compose.yaml)}"
psql -v ON_ERROR_STOP=1 --no-psqlrc --username "${POSTGRES_USER:-postgres}" \
    --dbname "${POSTGRES_DB:-postgres}" <<'EOSQL'
\set password `cat "$TRUECUT_DB_PASSWORD_FILE"`
CREATE ROLE truecut LOGIN NOSUPERUSER NOCREATEDB NOCREATEROLE NOREPLICATION PASSWORD :'password';
CREATE DATABASE truecut OWNER truecut;
REVOKE ALL ON DATABASE truecut FROM PUBLIC;
EOSQL
echo "10-truecut-role.sh: role truecut (no superuser) owns database truecut"
