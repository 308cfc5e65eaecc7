-- rigmon fleet: publish one site's historian tables for the central database (docs/fleet.md).
-- Run once on the site's PostgreSQL (started with wal_level = logical), after its historian
-- (config `[database] schema = "<schema>"`) has made its tables:
--   psql -v schema=site_north -f config/fleet/site-publication.sql
-- Every table a CM engineer reads is published; `rigmon_schema_migrations` is not (the central
-- copy is migrated by `rigmon historian --check`). `publish_via_partition_root`: the daily
-- `windows` and monthly `minutes` partitions are sent as their parent table, so the central
-- database needs none of the site's partition names.
CREATE PUBLICATION rigmon_fleet FOR TABLE
    :"schema".sites, :"schema".machines, :"schema".assets, :"schema".points, :"schema".models,
    :"schema".windows, :"schema".minutes, :"schema".events, :"schema".point_latest,
    :"schema".point_status
    WITH (publish_via_partition_root = true);
