-- Scale-out (several instances on one database). Keep in step with migrations/postgres/0003.
-- Instances: one row per running process, renewed by its heartbeat; an instance whose
-- heartbeat_at + lease_ms lies in the past (database clock) is gone, and its jobs are
-- re-queued or failed by whichever instance notices first.
CREATE TABLE instances (
    id           TEXT PRIMARY KEY,
    host         TEXT NOT NULL,
    started_at   INTEGER NOT NULL,
    heartbeat_at INTEGER NOT NULL,
    lease_ms     INTEGER NOT NULL
);

-- A job's input (JSON text its runner reads), so that any instance can claim and run it;
-- NULL for in-process work only its submitter can run. attempts counts the claims.
ALTER TABLE jobs ADD COLUMN input TEXT;
ALTER TABLE jobs ADD COLUMN attempts INTEGER NOT NULL DEFAULT 0;
CREATE INDEX jobs_state_created ON jobs (state, created_at);

-- Every saved model version: the container bytes in `data` (PostgreSQL) or, when NULL, a
-- file under the data dir (SQLite). `job` names the job that made it, if any.
CREATE TABLE model_versions (
    machine        TEXT NOT NULL REFERENCES machines(id) ON DELETE CASCADE,
    surface        TEXT NOT NULL,
    kind           TEXT NOT NULL,
    version        INTEGER NOT NULL,
    format_version INTEGER NOT NULL,
    sha256         TEXT NOT NULL,
    bytes          INTEGER NOT NULL,
    created_at     INTEGER NOT NULL,
    job            TEXT,
    data           BLOB,
    PRIMARY KEY (machine, surface, kind, version)
);

-- models: one row per model, naming the version served (`version`) and the last one made.
ALTER TABLE models ADD COLUMN version INTEGER NOT NULL DEFAULT 1;
ALTER TABLE models ADD COLUMN last_version INTEGER NOT NULL DEFAULT 1;
INSERT INTO model_versions (machine, surface, kind, version, format_version, sha256, bytes, created_at)
    SELECT machine, surface, kind, 1, format_version, sha256, bytes, updated_at FROM models;
