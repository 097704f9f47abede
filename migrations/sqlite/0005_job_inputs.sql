-- A stored job's input moves to a table of its own. Keep in step with migrations/postgres/0005.
-- In jobs it was rewritten by every write to the row: SQLite rewrites a whole record on
-- UPDATE, so each progress report (every 250 ms while a job runs) copied the input (20 MB for
-- a 1,000,000-sample decomposition) into the write-ahead log. A job has stored input
-- (any instance may claim it) exactly when it has a row here; the row goes when the job ends.
CREATE TABLE job_inputs (
    id    TEXT PRIMARY KEY REFERENCES jobs(id) ON DELETE CASCADE,
    input TEXT NOT NULL
);
INSERT INTO job_inputs (id, input) SELECT id, input FROM jobs WHERE input IS NOT NULL;
ALTER TABLE jobs DROP COLUMN input;
