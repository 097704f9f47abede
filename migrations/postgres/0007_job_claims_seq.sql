-- Keep in step with migrations/sqlite/0007. Two job columns (issue 41, items 4 and 9).
--
-- free_claims: claims of the job given back through no fault of its own (a database outage
-- met while storing its outcome, a claim whose answer was lost, a graceful stop, a worker
-- that ended without its outcome recorded). `attempts` still counts every claim (it is the
-- epoch that fences a worker's writes); the attempt limit applies to
-- `attempts - free_claims`, the claims that ended in a crash or are running. An instance
-- of an earlier release never gives a claim back, so it only over-counts, as before.
ALTER TABLE jobs ADD COLUMN free_claims BIGINT NOT NULL DEFAULT 0;

-- seq: the order jobs were recorded in, taken from the database (a sequence), not from the
-- inserting host's clock: the job list's cursor is on it, so a job recorded by an instance
-- whose clock is behind cannot fall into a page the client has already read. Existing jobs
-- are numbered in their creation order.
CREATE SEQUENCE jobs_seq;
ALTER TABLE jobs ADD COLUMN seq BIGINT;
UPDATE jobs SET seq = n.rn
  FROM (SELECT id, ROW_NUMBER() OVER (ORDER BY created_at, id) AS rn FROM jobs) AS n
  WHERE jobs.id = n.id;
SELECT setval('jobs_seq', COALESCE((SELECT MAX(seq) FROM jobs), 0) + 1, false);
ALTER TABLE jobs ALTER COLUMN seq SET DEFAULT nextval('jobs_seq');
ALTER TABLE jobs ALTER COLUMN seq SET NOT NULL;
ALTER SEQUENCE jobs_seq OWNED BY jobs.seq;
CREATE UNIQUE INDEX jobs_seq_unique ON jobs (seq);

-- request_id: the X-Request-Id of the request that queued the job, so that the log lines of
-- its run (on whichever instance claims it) can be tied to that request.
ALTER TABLE jobs ADD COLUMN request_id TEXT;
