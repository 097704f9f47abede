-- truecut schema v1 (SQLite). Keep in step with migrations/postgres/0001_init.sql.
-- Times are Unix milliseconds; arrays of numbers are little-endian f64 BLOBs.

CREATE TABLE machines (
    id          TEXT PRIMARY KEY,
    definition  TEXT NOT NULL,
    created_at  INTEGER NOT NULL,
    updated_at  INTEGER NOT NULL
);

CREATE TABLE surfaces (
    machine     TEXT NOT NULL REFERENCES machines(id) ON DELETE CASCADE,
    id          TEXT NOT NULL,
    nu          INTEGER NOT NULL,
    nv          INTEGER NOT NULL,
    points      BLOB NOT NULL,
    normals     BLOB NOT NULL,
    tool_radius REAL,
    extra       TEXT NOT NULL,
    created_at  INTEGER NOT NULL,
    updated_at  INTEGER NOT NULL,
    PRIMARY KEY (machine, id)
);

CREATE TABLE measurements (
    machine     TEXT NOT NULL,
    surface     TEXT NOT NULL,
    id          TEXT NOT NULL,
    n           INTEGER NOT NULL,
    max_abs     REAL NOT NULL,
    mean_abs    REAL NOT NULL,
    deviations  BLOB NOT NULL,
    points      BLOB,
    created_at  INTEGER NOT NULL,
    PRIMARY KEY (machine, surface, id),
    FOREIGN KEY (machine, surface) REFERENCES surfaces(machine, id) ON DELETE CASCADE
);

CREATE TABLE docs (
    machine     TEXT NOT NULL REFERENCES machines(id) ON DELETE CASCADE,
    kind        TEXT NOT NULL,
    key         TEXT NOT NULL,
    body        TEXT NOT NULL,
    updated_at  INTEGER NOT NULL,
    PRIMARY KEY (machine, kind, key)
);

CREATE TABLE models (
    machine        TEXT NOT NULL REFERENCES machines(id) ON DELETE CASCADE,
    surface        TEXT NOT NULL,
    kind           TEXT NOT NULL,
    format_version INTEGER NOT NULL,
    sha256         TEXT NOT NULL,
    bytes          INTEGER NOT NULL,
    updated_at     INTEGER NOT NULL,
    PRIMARY KEY (machine, surface, kind)
);

CREATE TABLE jobs (
    id          TEXT PRIMARY KEY,
    kind        TEXT NOT NULL,
    state       TEXT NOT NULL,
    progress    REAL NOT NULL,
    result      TEXT,
    error       TEXT,
    owner       TEXT NOT NULL,
    created_at  INTEGER NOT NULL,
    updated_at  INTEGER NOT NULL
);

CREATE INDEX jobs_owner_state ON jobs (owner, state);
