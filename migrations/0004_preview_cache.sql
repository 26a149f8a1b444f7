-- The preview cache is bounded by bytes: each entry's size, and when it was last used
-- (least recently used entries are evicted first).
ALTER TABLE previews ADD COLUMN bytes BIGINT NOT NULL DEFAULT 0;
ALTER TABLE previews ADD COLUMN used_ms BIGINT NOT NULL DEFAULT 0;
CREATE INDEX previews_used ON previews (used_ms);
