-- When a job started running and when it ended (Unix ms), for GET /v1/jobs; NULL until then.
ALTER TABLE jobs ADD COLUMN started_at BIGINT;
ALTER TABLE jobs ADD COLUMN finished_at BIGINT;
CREATE INDEX jobs_created ON jobs (created_at);
