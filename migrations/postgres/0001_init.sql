-- truecut schema v1 (PostgreSQL). Keep in step with migrations/sqlite/0001_init.sql.
-- Times are Unix milliseconds; arrays of numbers are little-endian f64 BYTEAs.

CREATE TABLE machines (
    id          TEXT PRIMARY KEY,
    definition  TEXT NOT NULL,
    created_at  BIGINT NOT NULL,
    updated_at  BIGINT NOT NULL
);

CREATE TABLE surfaces (
    machine     TEXT NOT NULL REFERENCES machines(id) ON DELETE CASCADE,
    id          TEXT NOT NULL,
    nu          BIGINT NOT NULL,
    nv          BIGINT NOT NULL,
    points      BYTEA NOT NULL,
    normals     BYTEA NOT NULL,
    tool_radius DOUBLE PRECISION,
    extra       TEXT NOT NULL,
    created_at  BIGINT NOT NULL,
    updated_at  BIGINT NOT NULL,
    PRIMARY KEY (machine, id)
);

CREATE TABLE measurements (
    machine     TEXT NOT NULL,
    surface     TEXT NOT NULL,
    id          TEXT NOT NULL,
    n           BIGINT NOT NULL,
    max_abs     DOUBLE PRECISION NOT NULL,
    mean_abs    DOUBLE PRECISION NOT NULL,
    deviations  BYTEA NOT NULL,
    points      BYTEA,
    created_at  BIGINT NOT NULL,
    PRIMARY KEY (machine, surface, id),
    FOREIGN KEY (machine, surface) REFERENCES surfaces(machine, id) ON DELETE CASCADE
);

CREATE TABLE docs (
    machine     TEXT NOT NULL REFERENCES machines(id) ON DELETE CASCADE,
    kind        TEXT NOT NULL,
    key         TEXT NOT NULL,
    body        TEXT NOT NULL,
    updated_at  BIGINT NOT NULL,
    PRIMARY KEY (machine, kind, key)
);

CREATE TABLE models (
    machine        TEXT NOT NULL REFERENCES machines(id) ON DELETE CASCADE,
    surface        TEXT NOT NULL,
    kind           TEXT NOT NULL,
    format_version BIGINT NOT NULL,
    sha256         TEXT NOT NULL,
    bytes          BIGINT NOT NULL,
    updated_at     BIGINT NOT NULL,
    PRIMARY KEY (machine, surface, kind)
);

CREATE TABLE jobs (
    id          TEXT PRIMARY KEY,
    kind        TEXT NOT NULL,
    state       TEXT NOT NULL,
    progress    DOUBLE PRECISION NOT NULL,
    result      TEXT,
    error       TEXT,
    owner       TEXT NOT NULL,
    created_at  BIGINT NOT NULL,
    updated_at  BIGINT NOT NULL
);

CREATE INDEX jobs_owner_state ON jobs (owner, state);

-- Number arrays are incompressible doubles: store them out of line without pglz compression
-- (compressing megabytes of doubles costs time and saves almost nothing).
ALTER TABLE surfaces ALTER COLUMN points SET STORAGE EXTERNAL;
ALTER TABLE surfaces ALTER COLUMN normals SET STORAGE EXTERNAL;
ALTER TABLE measurements ALTER COLUMN deviations SET STORAGE EXTERNAL;
ALTER TABLE measurements ALTER COLUMN points SET STORAGE EXTERNAL;
