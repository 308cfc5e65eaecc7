-- rigmon fleet: subscribe the central database to one site (docs/fleet.md).
-- Run once per site on the central PostgreSQL, after `rigmon historian --check` with the
-- site's `[database] schema` and the central database's PG* settings made the tables:
--   psql -v schema=site_north \
--        -v conninfo='host=north.plant port=5432 dbname=rigmon user=rigmon passfile=/var/lib/postgresql/sites.pgpass' \
--        -f config/fleet/central-subscription.sql
-- The site's password comes from a pgpass file the central server's OS user owns (mode 0600),
-- never from the CONNECTION string (which the catalog would keep). Rows of days and months
-- for which no partition exists land in the default partitions made here; the central copy
-- keeps everything (site retention drops whole partitions, which is not replicated).
CREATE TABLE IF NOT EXISTS :"schema".windows_default PARTITION OF :"schema".windows DEFAULT;
CREATE TABLE IF NOT EXISTS :"schema".minutes_default PARTITION OF :"schema".minutes DEFAULT;
\set sub rigmon_ :schema
CREATE SUBSCRIPTION :"sub" CONNECTION :'conninfo' PUBLICATION rigmon_fleet;
