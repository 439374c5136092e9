-- Jobs, their uploaded inputs, the tasks workers claim, ratings and the workers seen.
-- Times are milliseconds since the Unix epoch. The SQLite schema is the same in its types.
CREATE TABLE jobs (
    key TEXT PRIMARY KEY,
    kind TEXT NOT NULL,
    state TEXT NOT NULL,
    params TEXT NOT NULL,
    name TEXT,
    email TEXT,
    client TEXT,
    width BIGINT NOT NULL,
    height BIGINT NOT NULL,
    created_ms BIGINT NOT NULL,
    started_ms BIGINT,
    finished_ms BIGINT,
    error TEXT,
    timings TEXT,
    result_exr BYTEA,
    result_png BYTEA,
    input_png BYTEA
);
CREATE INDEX jobs_state ON jobs (state, created_ms);

CREATE TABLE inputs (
    job_key TEXT NOT NULL REFERENCES jobs (key) ON DELETE CASCADE,
    name TEXT NOT NULL,
    format TEXT NOT NULL,
    data BYTEA NOT NULL,
    PRIMARY KEY (job_key, name)
);

CREATE TABLE tasks (
    id BIGSERIAL PRIMARY KEY,
    job_key TEXT NOT NULL REFERENCES jobs (key) ON DELETE CASCADE,
    kind TEXT NOT NULL,
    first_sample BIGINT NOT NULL,
    samples BIGINT NOT NULL,
    state TEXT NOT NULL,
    worker TEXT,
    lease_until_ms BIGINT,
    attempts BIGINT NOT NULL DEFAULT 0,
    progress DOUBLE PRECISION NOT NULL DEFAULT 0,
    completed_by TEXT,
    output BYTEA
);
CREATE INDEX tasks_claim ON tasks (state, id);
CREATE INDEX tasks_job ON tasks (job_key);

CREATE TABLE ratings (
    job_key TEXT PRIMARY KEY REFERENCES jobs (key) ON DELETE CASCADE,
    rating BIGINT NOT NULL,
    comment TEXT,
    created_ms BIGINT NOT NULL
);

CREATE TABLE workers (
    id TEXT PRIMARY KEY,
    host TEXT NOT NULL,
    started_ms BIGINT NOT NULL,
    last_seen_ms BIGINT NOT NULL,
    tasks_done BIGINT NOT NULL DEFAULT 0
);
