//! Writing a batch: the points and models it names are registered first (asset tree upserts,
//! cached), its partitions made, then one transaction: binary `COPY` into a temporary staging
//! table, `INSERT .. ON CONFLICT DO NOTHING` into `windows` (so replays and retries never
//! duplicate) whose *inserted* rows alone feed the 1-minute aggregates and the latest window
//! per point, one event per state change (with the state it left, how long that held, and
//! the full JSON), and the daemons' latest status. Exactly once, or not at all.

use super::columns;
use super::database::Target;
use super::migrations;
use super::partitions::Partitions;
use super::row::{ns_of, time_of, ModelKey, PointInfo, WindowRow};
use anyhow::{Context, Result};
use rigmon_core::health::UNKNOWN;
use rigmon_core::vocabulary::Condition;
use rigmon_core::wire::status::StatusMessage;
use std::collections::HashMap;
use std::time::SystemTime;
use tokio_postgres::binary_copy::BinaryCopyInWriter;
use tokio_postgres::types::Type;
use tokio_postgres::Client;

/// A daemon's status message as a `point_status` row.
#[derive(Debug, Clone)]
pub struct StatusRow {
    pub key: String,
    pub time: SystemTime,
    pub phase: String,
    pub state: Option<String>,
    pub windows: i64,
    pub connected: bool,
    pub samples_lost: i64,
    pub bad_frames: i64,
    pub sink_dropped: i64,
    pub message: serde_json::Value,
}

impl StatusRow {
    /// Read one status message (JSON).
    pub fn parse(payload: &[u8]) -> Result<StatusRow> {
        let s: StatusMessage = serde_json::from_slice(payload)
            .map_err(|e| anyhow::anyhow!("not a rigmon.status message: {e}"))?;
        let i = |v: u64| i64::try_from(v).unwrap_or(i64::MAX);
        Ok(StatusRow {
            key: format!("{}/{}/{}", s.rig, s.asset, s.point),
            time: time_of(s.time_ns),
            phase: serde_json::to_value(s.phase)?
                .as_str()
                .unwrap_or("")
                .to_string(),
            state: s.state.clone(),
            windows: i(s.pipeline.windows),
            connected: s.source.connected,
            samples_lost: i(s.source.samples_lost + s.pipeline.samples_lost),
            bad_frames: i(s.source.bad_frames),
            sink_dropped: i(s.sinks.zenoh_dropped + s.sinks.record_dropped),
            message: serde_json::from_slice(payload)?,
        })
    }
}

/// What one batch did.
#[derive(Debug, Default, Clone)]
pub struct Outcome {
    pub inserted: u64,
    pub duplicates: u64,
    pub events: u64,
    /// Points registered for the first time by this historian: (point_id, key).
    pub new_points: Vec<(i32, String)>,
}

/// One database connection that writes.
pub struct Writer {
    client: Client,
    points: HashMap<String, (i32, PointInfo)>,
    models: HashMap<ModelKey, i32>,
    partitions: Partitions,
    copy_sql: String,
    copy_types: Vec<Type>,
    insert_sql: String,
}

/// Every new or changed point of a batch registered in one statement (sites, machines, assets,
/// points), instead of one round trip per point: 5,000 new points took seconds before.
/// Input arrays: site, machine, asset, point, key, band channel, band orders, calibration,
/// software version; one element per distinct key.
const POINTS_UPSERT: &str = "
WITH i AS (SELECT * FROM unnest($1::text[], $2::text[], $3::text[], $4::text[], $5::text[],
                                $6::text[], $7::jsonb[], $8::text[], $9::text[])
           AS t(site, machine, asset, point, key, band_channel, band_orders, calibration_id,
                software_version)),
     s AS (INSERT INTO sites (name) SELECT DISTINCT site FROM i ORDER BY 1
           ON CONFLICT (name) DO UPDATE SET name = excluded.name RETURNING site_id, name),
     m AS (INSERT INTO machines (site_id, name)
           SELECT DISTINCT ON (i.machine) s.site_id, i.machine FROM i JOIN s ON s.name = i.site
           ORDER BY i.machine
           ON CONFLICT (name) DO UPDATE SET site_id = excluded.site_id
           RETURNING machine_id, name),
     a AS (INSERT INTO assets (machine_id, name)
           SELECT DISTINCT m.machine_id, i.asset FROM i JOIN m ON m.name = i.machine ORDER BY 1, 2
           ON CONFLICT (machine_id, name) DO UPDATE SET name = excluded.name
           RETURNING asset_id, machine_id, name)
INSERT INTO points (asset_id, name, key, band_channel, band_orders, calibration_id, software_version)
SELECT a.asset_id, i.point, i.key, i.band_channel, i.band_orders, i.calibration_id,
       i.software_version
FROM i JOIN m ON m.name = i.machine JOIN a ON a.machine_id = m.machine_id AND a.name = i.asset
ORDER BY i.key
ON CONFLICT (key) DO UPDATE SET asset_id = excluded.asset_id, band_channel = excluded.band_channel,
    band_orders = excluded.band_orders, calibration_id = excluded.calibration_id,
    software_version = excluded.software_version
RETURNING point_id, key";

const MODEL_UPSERT: &str = "INSERT INTO models (name, sha256, labels) VALUES ($1, $2, $3)
    ON CONFLICT (name, sha256, labels) DO UPDATE SET name = excluded.name RETURNING model_id";

/// State-change events: the state left and how long it held come from the window before.
const EVENTS_SQL: &str = "
INSERT INTO events (point_id, time, from_state, to_state, previous_since, held_s, confidence, message)
SELECT s.point_id, s.time, prev.state, s.state, prev.state_since,
       extract(epoch FROM s.time - prev.state_since), s.confidence, s.message
FROM staging s
LEFT JOIN LATERAL (SELECT w.state, w.state_since FROM windows w
                   WHERE w.point_id = s.point_id AND w.time < s.time
                   ORDER BY w.time DESC LIMIT 1) prev ON true
WHERE s.state_changed AND s.message IS NOT NULL
ON CONFLICT (point_id, time) DO NOTHING";

const STATUS_UPSERT: &str = "
INSERT INTO point_status AS s (point_id, time, phase, state, windows, source_connected,
                               samples_lost, bad_frames, sink_dropped, message)
SELECT * FROM unnest($1::int4[], $2::timestamptz[], $3::text[], $4::text[], $5::int8[],
                     $6::bool[], $7::int8[], $8::int8[], $9::int8[], $10::jsonb[])
ON CONFLICT (point_id) DO UPDATE SET time = excluded.time, phase = excluded.phase,
    state = excluded.state, windows = excluded.windows,
    source_connected = excluded.source_connected, samples_lost = excluded.samples_lost,
    bad_frames = excluded.bad_frames, sink_dropped = excluded.sink_dropped,
    message = excluded.message
WHERE excluded.time > s.time";

/// The insert with its aggregates, from the column table ([`columns`]); $1 = the unknown
/// state, $2 = the healthy label.
fn insert_sql() -> String {
    let cols = columns::names();
    let returned = columns::returned();
    let (agg_cols, agg_exprs, agg_merges) = columns::minute_sql();
    let (latest, latest_updates) = columns::latest_sql();
    format!(
        "WITH ins AS (
    INSERT INTO windows ({cols}) SELECT {cols} FROM staging ON CONFLICT DO NOTHING
    RETURNING {returned}
), agg AS (
    INSERT INTO minutes AS m (point_id, minute, windows, bad_quality, unknown_windows,
        fault_windows, last_time, last_state, {agg_cols})
    SELECT point_id, date_bin('1 minute', time, TIMESTAMPTZ '2000-01-01 00:00:00+00'),
        count(*), count(*) FILTER (WHERE NOT quality_ok), count(*) FILTER (WHERE state = $1),
        count(*) FILTER (WHERE state <> $1 AND state <> $2), max(time),
        (array_agg(state ORDER BY time DESC))[1], {agg_exprs}
    FROM ins GROUP BY 1, 2
    ON CONFLICT (point_id, minute) DO UPDATE SET
        windows = m.windows + excluded.windows,
        bad_quality = m.bad_quality + excluded.bad_quality,
        unknown_windows = m.unknown_windows + excluded.unknown_windows,
        fault_windows = m.fault_windows + excluded.fault_windows,
        last_state = CASE WHEN excluded.last_time > m.last_time THEN excluded.last_state
                          ELSE m.last_state END,
        last_time = greatest(m.last_time, excluded.last_time),
        {agg_merges}
), latest AS (
    INSERT INTO point_latest AS l ({latest})
    SELECT DISTINCT ON (point_id) {latest}
    FROM ins ORDER BY point_id, time DESC
    ON CONFLICT (point_id) DO UPDATE SET {latest_updates}
    WHERE excluded.time > l.time
)
SELECT count(*) FROM ins"
    )
}

impl Writer {
    /// Connect, apply the migrations (in `[database] schema`, made if missing), prepare the
    /// staging table. Returns the schema version.
    pub async fn open(target: &Target) -> Result<(Writer, i32)> {
        let mut client = target.connect().await?;
        if let Some(schema) = target.schema() {
            client
                .batch_execute(&format!("CREATE SCHEMA IF NOT EXISTS \"{schema}\""))
                .await
                .with_context(|| format!("creating schema {schema} ([database] schema)"))?;
        }
        migrations::apply(&mut client).await?;
        let version = migrations::current(&client).await?;
        columns::check(&client, version).await?;
        client
            .batch_execute(
                "CREATE TEMP TABLE staging (LIKE windows) ON COMMIT DELETE ROWS;
                 ALTER TABLE staging ADD COLUMN message jsonb;",
            )
            .await
            .context("creating the staging table")?;
        Ok((
            Writer {
                client,
                points: HashMap::new(),
                models: HashMap::new(),
                partitions: Partitions::default(),
                copy_sql: format!(
                    "COPY staging ({}, message) FROM STDIN (FORMAT binary)",
                    columns::names()
                ),
                copy_types: columns::copy_types(),
                insert_sql: insert_sql(),
            },
            version,
        ))
    }

    /// `synchronous_commit` for this session. `off` is PostgreSQL's documented trade for bulk
    /// ingest: a commit returns before its WAL is flushed, so a database *crash* can forget
    /// the last ~0.6 s (3 x `wal_writer_delay`) of acknowledged batches, never corrupt
    /// anything; the service re-seeds its gap tracker from the database on every reconnect,
    /// so such windows are asked again of the daemons' recent history.
    pub async fn set_synchronous_commit(&self, on: bool) -> Result<()> {
        let v = if on { "on" } else { "off" };
        self.client
            .batch_execute(&format!("SET synchronous_commit = {v}"))
            .await
            .with_context(|| format!("SET synchronous_commit = {v}"))
    }

    pub fn client(&self) -> &Client {
        &self.client
    }

    pub fn is_closed(&self) -> bool {
        self.client.is_closed()
    }

    /// The last window per point in the database: key -> (run start ns, seq).
    pub async fn last_positions(&self) -> Result<HashMap<String, (u64, u64)>> {
        let rows = self
            .client
            .query(
                "SELECT p.key, l.run_start, l.seq FROM point_latest l JOIN points p USING (point_id)",
                &[],
            )
            .await?;
        Ok(rows
            .iter()
            .map(|r| {
                let run: SystemTime = r.get(1);
                let seq: i64 = r.get(2);
                (r.get::<_, String>(0), (ns_of(run), seq.max(0) as u64))
            })
            .collect())
    }

    /// Register the batch's new or changed points in one statement; fill in every row's id.
    async fn point_ids(
        &mut self,
        rows: &mut [WindowRow],
        new_points: &mut Vec<(i32, String)>,
    ) -> Result<()> {
        let mut todo: HashMap<String, &PointInfo> = HashMap::new();
        for r in rows.iter() {
            let key = r.point.key();
            let known = self.points.get(&key).is_some_and(|(_, p)| *p == r.point);
            if !known {
                todo.insert(key, &r.point);
            }
        }
        if !todo.is_empty() {
            let mut list: Vec<(String, PointInfo)> =
                todo.into_iter().map(|(k, p)| (k, p.clone())).collect();
            list.sort_by(|a, b| a.0.cmp(&b.0));
            let col =
                |f: fn(&PointInfo) -> String| list.iter().map(|(_, p)| f(p)).collect::<Vec<_>>();
            let keys: Vec<String> = list.iter().map(|(k, _)| k.clone()).collect();
            let orders: Vec<serde_json::Value> =
                list.iter().map(|(_, p)| p.band_orders.clone()).collect();
            let calibration: Vec<Option<String>> =
                list.iter().map(|(_, p)| p.calibration_id.clone()).collect();
            let (site, machine, asset, point, channel, version) = (
                col(|p| p.site.clone()),
                col(|p| p.machine.clone()),
                col(|p| p.asset.clone()),
                col(|p| p.point.clone()),
                col(|p| p.band_channel.clone()),
                col(|p| p.software_version.clone()),
            );
            let got = self
                .client
                .query(
                    POINTS_UPSERT,
                    &[
                        &site,
                        &machine,
                        &asset,
                        &point,
                        &keys,
                        &channel,
                        &orders,
                        &calibration,
                        &version,
                    ],
                )
                .await
                .with_context(|| format!("registering {} points in the asset tree", keys.len()))?;
            let ids: HashMap<String, i32> = got.iter().map(|r| (r.get(1), r.get(0))).collect();
            for (key, info) in list {
                let Some(&id) = ids.get(&key) else {
                    anyhow::bail!("registering point {key} in the asset tree returned no id");
                };
                if !self.points.contains_key(&key) {
                    new_points.push((id, key.clone()));
                }
                self.points.insert(key, (id, info));
            }
        }
        for r in rows.iter_mut() {
            r.point_id = self.points.get(&r.point.key()).map_or(0, |p| p.0);
        }
        Ok(())
    }

    async fn model_id(&mut self, m: &ModelKey) -> Result<i32> {
        if let Some(id) = self.models.get(m) {
            return Ok(*id);
        }
        let row = self
            .client
            .query_one(MODEL_UPSERT, &[&m.name, &m.sha256, &m.labels])
            .await
            .with_context(|| format!("registering model {}", m.name))?;
        let id: i32 = row.get(0);
        self.models.insert(m.clone(), id);
        Ok(id)
    }

    /// The point id of a key already registered (statuses of unknown points wait).
    fn known_point(&self, key: &str) -> Option<i32> {
        self.points.get(key).map(|p| p.0)
    }

    /// Load the ids of points already in the database (for their status rows).
    pub async fn load_points(&mut self) -> Result<()> {
        let rows = self
            .client
            .query("SELECT point_id, key FROM points", &[])
            .await?;
        for r in rows {
            let key: String = r.get(1);
            self.points.entry(key.clone()).or_insert((
                r.get(0),
                PointInfo {
                    site: String::new(),
                    machine: String::new(),
                    asset: String::new(),
                    point: key,
                    band_channel: String::new(),
                    band_orders: serde_json::Value::Null,
                    calibration_id: None,
                    software_version: String::new(),
                },
            ));
        }
        Ok(())
    }

    /// Write one batch in one transaction.
    pub async fn write(
        &mut self,
        rows: &mut [WindowRow],
        statuses: &[StatusRow],
    ) -> Result<Outcome> {
        let mut new_points = Vec::new();
        self.prepare(rows, &mut new_points).await?;
        let mut out = self.write_prepared(rows, statuses).await?;
        out.new_points = new_points;
        Ok(out)
    }

    /// What a batch needs before its transaction, each its own statement: its new points
    /// registered (pushed to `new_points`), its models, its partitions; every row's ids set.
    pub async fn prepare(
        &mut self,
        rows: &mut [WindowRow],
        new_points: &mut Vec<(i32, String)>,
    ) -> Result<()> {
        self.point_ids(rows, new_points).await?;
        for r in rows.iter_mut() {
            r.model_id = self.model_id(&r.model).await?;
        }
        self.partitions
            .ensure(&self.client, rows.iter().map(|r| r.time))
            .await
    }

    /// The batch's transaction (rows [`Writer::prepare`]d by this writer): COPY, insert with
    /// aggregates and latest, events, statuses, commit.
    pub async fn write_prepared(
        &mut self,
        rows: &[WindowRow],
        statuses: &[StatusRow],
    ) -> Result<Outcome> {
        let mut out = Outcome::default();
        let statuses = self.latest_statuses(statuses);
        let times: Vec<_> = rows.iter().map(|r| r.times()).collect();
        let tx = self.client.transaction().await?;
        if !rows.is_empty() {
            let sink = tx
                .copy_in(&self.copy_sql)
                .await
                .context("COPY into staging")?;
            let mut copy = std::pin::pin!(BinaryCopyInWriter::new(sink, &self.copy_types));
            for (r, t) in rows.iter().zip(&times) {
                copy.as_mut()
                    .write(&columns::copy_values(r, t))
                    .await
                    .context("COPY row")?;
            }
            copy.as_mut().finish().await.context("COPY finish")?;
            let healthy = Condition::Healthy.as_str();
            let inserted: i64 = tx
                .query_one(&self.insert_sql, &[&UNKNOWN, &healthy])
                .await
                .context("inserting windows and aggregates")?
                .get(0);
            out.inserted = inserted.max(0) as u64;
            out.duplicates = rows.len() as u64 - out.inserted;
            out.events = tx
                .execute(EVENTS_SQL, &[])
                .await
                .context("inserting events")?;
        }
        if !statuses.is_empty() {
            write_statuses(&tx, &statuses).await?;
        }
        tx.commit().await.context("commit")?;
        Ok(out)
    }

    /// The newest status per known point.
    fn latest_statuses(&self, statuses: &[StatusRow]) -> Vec<(i32, StatusRow)> {
        let mut by_point: HashMap<i32, StatusRow> = HashMap::new();
        for s in statuses {
            if let Some(id) = self.known_point(&s.key) {
                let newer = by_point.get(&id).is_none_or(|o| s.time > o.time);
                if newer {
                    by_point.insert(id, s.clone());
                }
            }
        }
        by_point.into_iter().collect()
    }

    /// Store a point's ISO 20816-3 zone limits (learned from its daemon's config).
    pub async fn set_iso_limits(&self, point_id: i32, limits: [f64; 3]) -> Result<()> {
        let l: Vec<f32> = limits.iter().map(|&v| v as f32).collect();
        self.client
            .execute(
                "UPDATE points SET iso_limits_mm_s = $1 WHERE point_id = $2",
                &[&l, &point_id],
            )
            .await?;
        Ok(())
    }

    /// Drop partitions past their retention.
    pub async fn retention(&self, windows_days: u32, minutes_days: u32) -> Result<Vec<String>> {
        super::partitions::apply_retention(
            &self.client,
            windows_days,
            minutes_days,
            SystemTime::now(),
        )
        .await
    }

    /// After a reconnect nothing cached may be trusted but the ids.
    pub fn forget_partitions(&mut self) {
        self.partitions.forget();
    }
}

async fn write_statuses(
    tx: &tokio_postgres::Transaction<'_>,
    statuses: &[(i32, StatusRow)],
) -> Result<()> {
    let ids: Vec<i32> = statuses.iter().map(|s| s.0).collect();
    let col = |f: fn(&StatusRow) -> i64| statuses.iter().map(|s| f(&s.1)).collect::<Vec<i64>>();
    let times: Vec<SystemTime> = statuses.iter().map(|s| s.1.time).collect();
    let phases: Vec<String> = statuses.iter().map(|s| s.1.phase.clone()).collect();
    let states: Vec<Option<String>> = statuses.iter().map(|s| s.1.state.clone()).collect();
    let connected: Vec<bool> = statuses.iter().map(|s| s.1.connected).collect();
    let messages: Vec<serde_json::Value> = statuses.iter().map(|s| s.1.message.clone()).collect();
    let (windows, lost, bad, dropped) = (
        col(|s| s.windows),
        col(|s| s.samples_lost),
        col(|s| s.bad_frames),
        col(|s| s.sink_dropped),
    );
    tx.execute(
        STATUS_UPSERT,
        &[
            &ids, &times, &phases, &states, &windows, &connected, &lost, &bad, &dropped, &messages,
        ],
    )
    .await
    .context("writing daemon status")?;
    Ok(())
}

/// True when an error means the connection is gone (retry after reconnecting) rather than
/// the data being refused.
pub fn is_connection_error(e: &anyhow::Error, closed: bool) -> bool {
    if closed {
        return true;
    }
    for cause in e.chain() {
        if let Some(pg) = cause.downcast_ref::<tokio_postgres::Error>() {
            return match pg.as_db_error() {
                None => true,
                Some(db) => {
                    let code = db.code().code();
                    code.starts_with("08") || code.starts_with("57") || code.starts_with("53")
                }
            };
        }
    }
    false
}
