-- ISO 230-2 runs stored per machine axis, so that the figures before and after compensation
-- can be compared. `input` is the table evaluated (JSON: targets, forward, backward, mm),
-- `answer` the route's answer (JSON, mm). Times are Unix milliseconds.
CREATE TABLE iso230_runs (
    machine     TEXT NOT NULL REFERENCES machines(id) ON DELETE CASCADE,
    axis        TEXT NOT NULL,
    id          TEXT NOT NULL,
    label       TEXT,
    input       TEXT NOT NULL,
    answer      TEXT NOT NULL,
    created_at  INTEGER NOT NULL,
    PRIMARY KEY (machine, axis, id)
);
CREATE INDEX iso230_runs_created ON iso230_runs (machine, axis, created_at);
