-- Portable SQL: the same migrations run on SQLite and PostgreSQL. Ids are text (content
-- hashes or random hex), times are Unix milliseconds, JSON documents are text.

-- Uploaded inputs, deduplicated by content: id = BLAKE3 of the bytes (the blob's key).
CREATE TABLE assets (
    id TEXT PRIMARY KEY,
    kind TEXT NOT NULL,
    name TEXT NOT NULL,
    bytes BIGINT NOT NULL,
    summary TEXT NOT NULL,
    created_ms BIGINT NOT NULL
);

-- Bake jobs and their lease: a worker owns a running job until lease_expires_ms.
CREATE TABLE jobs (
    id TEXT PRIMARY KEY,
    dedup_key TEXT NOT NULL UNIQUE,
    spec TEXT NOT NULL,
    plan TEXT NOT NULL,
    state TEXT NOT NULL,
    stage TEXT,
    progress DOUBLE PRECISION NOT NULL,
    attempts INTEGER NOT NULL,
    max_attempts INTEGER NOT NULL,
    lease_owner TEXT,
    lease_expires_ms BIGINT,
    run_after_ms BIGINT NOT NULL,
    cancel_requested INTEGER NOT NULL,
    error TEXT,
    package_digest TEXT,
    timings TEXT NOT NULL,
    created_ms BIGINT NOT NULL,
    updated_ms BIGINT NOT NULL
);
CREATE INDEX jobs_claim ON jobs (state, run_after_ms);

-- Packages produced by jobs: digest = BLAKE3 of the package bytes (the blob's key).
CREATE TABLE packages (
    digest TEXT PRIMARY KEY,
    bytes BIGINT NOT NULL,
    manifest TEXT NOT NULL,
    created_ms BIGINT NOT NULL
);
