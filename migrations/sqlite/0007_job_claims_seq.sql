-- Keep in step with migrations/postgres/0007. Two job columns (issue 41, items 4 and 9).
--
-- free_claims: claims of the job given back through no fault of its own (a database outage
-- met while storing its outcome, a claim whose answer was lost, a graceful stop, a worker
-- that ended without its outcome recorded). `attempts` still counts every claim (it is the
-- epoch that fences a worker's writes); the attempt limit applies to
-- `attempts - free_claims`, the claims that ended in a crash or are running.
ALTER TABLE jobs ADD COLUMN free_claims INTEGER NOT NULL DEFAULT 0;

-- seq: the order jobs were recorded in, numbered by the database in the INSERT itself
-- (SQLite serialises writers, so MAX(seq) + 1 is unique), not by the inserting host's clock:
-- the job list's cursor is on it. Existing jobs are numbered in their creation order.
ALTER TABLE jobs ADD COLUMN seq INTEGER NOT NULL DEFAULT 0;
UPDATE jobs SET seq = (SELECT COUNT(*) FROM jobs AS o
                       WHERE o.created_at < jobs.created_at
                          OR (o.created_at = jobs.created_at AND o.id <= jobs.id));
CREATE UNIQUE INDEX jobs_seq_unique ON jobs (seq);

-- request_id: the X-Request-Id of the request that queued the job, so that the log lines of
-- its run (on whichever instance claims it) can be tied to that request.
ALTER TABLE jobs ADD COLUMN request_id TEXT;
