-- Idempotency keys (the Idempotency-Key header of POST uploads and job submissions). Keep in
-- step with migrations/sqlite/0006. One row per (scope, key): the scope is the route (method
-- and path) and a digest of the caller's token. While the first request runs, `status` is NULL
-- and `claim` names that request; once answered, the answer (status, kept headers as a JSON
-- array of [name, value] pairs, body) and the request's fingerprint (SHA-256 of its query and
-- body) are kept until pruned, 24 h after `created_at` (Unix ms).
CREATE TABLE idempotency_keys (
    scope       TEXT NOT NULL,
    key         TEXT NOT NULL,
    claim       TEXT NOT NULL,
    fingerprint TEXT,
    status      BIGINT,
    headers     TEXT,
    body        BYTEA,
    created_at  BIGINT NOT NULL,
    PRIMARY KEY (scope, key)
);
CREATE INDEX idempotency_keys_created ON idempotency_keys (created_at);
