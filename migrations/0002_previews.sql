-- Rendered previews: key = BLAKE3 of (scene, package digest); the PNG is a blob.
CREATE TABLE previews (
    cache_key TEXT PRIMARY KEY,
    png_digest TEXT NOT NULL,
    created_ms BIGINT NOT NULL
);
