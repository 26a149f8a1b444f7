-- API keys: only the BLAKE3 hash of a key is stored; scopes are a comma-separated list of
-- upload, bake, read.
CREATE TABLE api_keys (
    id TEXT PRIMARY KEY,
    key_hash TEXT NOT NULL UNIQUE,
    scopes TEXT NOT NULL,
    label TEXT NOT NULL,
    created_ms BIGINT NOT NULL,
    revoked INTEGER NOT NULL
);
