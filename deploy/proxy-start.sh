#!/bin/sh
# Runs nginx for the fleet (compose.yaml, service proxy) and reloads it when an instance comes
# back on another address.
#
# nginx resolves the upstream names of deploy/nginx.conf (truecut1..3) once, when it loads its
# configuration. An instance container that is recreated (a rolling upgrade: `up -d` with a new
# image) or restarted (the restart policy after a crash; podman always gives it a new address)
# may get another IP address, which nginx would never send a request to again: the fleet
# would shrink with every restart. Every 5 s this resolves the names as nginx does
# (getaddrinfo, through the container's resolver) and, when an address changed and every name
# resolves (a reload needs them all), reloads nginx: new workers take new connections, requests
# in flight finish on the old ones. nginx stays PID 1 (its stop signal, SIGQUIT, is graceful).
set -eu

names=${TRUECUT_UPSTREAMS:-truecut1 truecut2 truecut3}

addresses() {
    for name in $names; do
        address=$(getent hosts "$name" | awk '{print $1; exit}')
        [ -n "$address" ] || return 1
        printf '%s=%s ' "$name" "$address"
    done
}

(
    loaded=$(addresses || true)
    while sleep 5; do
        now=$(addresses) || continue
        if [ "$now" != "$loaded" ]; then
            echo "proxy-start: upstream addresses changed ($loaded-> $now); reloading nginx"
            nginx -s reload && loaded=$now
        fi
    done
) &

exec nginx -g 'daemon off;'
