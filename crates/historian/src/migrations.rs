//! Versioned schema migrations, applied by the historian on start: each is one SQL file in
//! `migrations/`, run in its own transaction and recorded in `rigmon_schema_migrations`, under
//! an advisory lock so two historians starting together do not race. A database whose schema
//! is newer than this rigmon knows is refused (upgrade rigmon first).

use anyhow::{bail, Context, Result};
use tokio_postgres::Client;

/// (version, name, SQL), in order.
pub const MIGRATIONS: &[(i32, &str, &str)] = &[
    (1, "schema", include_str!("migrations/0001_schema.sql")),
    (
        2,
        "decision_evidence_speed",
        include_str!("migrations/0002_decision_evidence_speed.sql"),
    ),
    (3, "impulse", include_str!("migrations/0003_impulse.sql")),
    (
        4,
        "indicators",
        include_str!("migrations/0004_indicators.sql"),
    ),
];

/// Advisory-lock key ("rigmon" in ASCII).
const LOCK: i64 = 0x7269_676d_6f6e;

/// The schema version this rigmon writes.
pub fn latest() -> i32 {
    MIGRATIONS.last().map_or(0, |m| m.0)
}

/// Apply every migration the database lacks; returns the versions applied now.
pub async fn apply(client: &mut Client) -> Result<Vec<i32>> {
    client
        .batch_execute(
            "CREATE TABLE IF NOT EXISTS rigmon_schema_migrations (
                version integer PRIMARY KEY,
                name text NOT NULL,
                applied_at timestamptz NOT NULL DEFAULT now())",
        )
        .await
        .context(
            "creating rigmon_schema_migrations (does the user may create tables in this database?)",
        )?;
    client
        .execute("SELECT pg_advisory_lock($1)", &[&LOCK])
        .await
        .context("taking the migration lock")?;
    let result = apply_locked(client).await;
    let _ = client
        .execute("SELECT pg_advisory_unlock($1)", &[&LOCK])
        .await;
    result
}

async fn apply_locked(client: &mut Client) -> Result<Vec<i32>> {
    let have: Option<i32> = client
        .query_one("SELECT max(version) FROM rigmon_schema_migrations", &[])
        .await?
        .get(0);
    let have = have.unwrap_or(0);
    if have > latest() {
        bail!(
            "the database's historian schema is version {have}, newer than this rigmon knows ({}); upgrade rigmon",
            latest()
        );
    }
    let mut applied = Vec::new();
    for (version, name, sql) in MIGRATIONS.iter().filter(|m| m.0 > have) {
        let tx = client.transaction().await?;
        tx.batch_execute(sql)
            .await
            .with_context(|| format!("migration {version} ({name}) failed"))?;
        tx.execute(
            "INSERT INTO rigmon_schema_migrations (version, name) VALUES ($1, $2)",
            &[version, name],
        )
        .await?;
        tx.commit().await?;
        tracing::info!("historian schema migration {version} ({name}) applied");
        applied.push(*version);
    }
    Ok(applied)
}

/// The schema version a database holds now (0 = none).
pub async fn current(client: &Client) -> Result<i32> {
    let exists: bool = client
        .query_one(
            "SELECT to_regclass('rigmon_schema_migrations') IS NOT NULL",
            &[],
        )
        .await?
        .get(0);
    if !exists {
        return Ok(0);
    }
    let v: Option<i32> = client
        .query_one("SELECT max(version) FROM rigmon_schema_migrations", &[])
        .await?
        .get(0);
    Ok(v.unwrap_or(0))
}
