//! The `windows` columns as one typed table ([`WINDOWS`]): each column's name, SQL type,
//! whether it may be NULL, how a [`WindowRow`] gives its value to the binary COPY, whether it
//! is kept in `point_latest` and how it is folded into the 1-minute aggregates. From it come
//! the COPY's column list and types ([`copy_values`]), the insert with its aggregates
//! ([`minute_sql`], [`latest_sql`]), the check that a database's tables match ([`check`], run
//! after the migrations) and the names the history query reads back ([`Read`]).

use super::row::{RowTimes, WindowRow};
use anyhow::{bail, Context, Result};
use std::collections::{BTreeSet, HashMap};
use std::sync::LazyLock;
use tokio_postgres::types::{FromSql, ToSql, Type};
use tokio_postgres::{Client, Row};

/// A column's SQL type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SqlType {
    Integer,
    Bigint,
    Real,
    Double,
    Text,
    Boolean,
    Timestamptz,
    Jsonb,
    TextArray,
}

impl SqlType {
    /// The type the binary COPY writes.
    pub fn pg_type(self) -> Type {
        match self {
            SqlType::Integer => Type::INT4,
            SqlType::Bigint => Type::INT8,
            SqlType::Real => Type::FLOAT4,
            SqlType::Double => Type::FLOAT8,
            SqlType::Text => Type::TEXT,
            SqlType::Boolean => Type::BOOL,
            SqlType::Timestamptz => Type::TIMESTAMPTZ,
            SqlType::Jsonb => Type::JSONB,
            SqlType::TextArray => Type::TEXT_ARRAY,
        }
    }

    /// The type as PostgreSQL's `format_type` names it.
    pub fn name(self) -> &'static str {
        match self {
            SqlType::Integer => "integer",
            SqlType::Bigint => "bigint",
            SqlType::Real => "real",
            SqlType::Double => "double precision",
            SqlType::Text => "text",
            SqlType::Boolean => "boolean",
            SqlType::Timestamptz => "timestamp with time zone",
            SqlType::Jsonb => "jsonb",
            SqlType::TextArray => "text[]",
        }
    }
}

/// How a column is folded into `minutes` (sums, so that means add up across batches).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Minute {
    None,
    /// `<into>_sum` (and `<into>_max` when `max`); `n` counts the windows that had a value
    /// (the first column naming an `n` counts it for all that share it).
    Mean {
        into: &'static str,
        max: bool,
        n: &'static str,
    },
    /// `<into>_max`.
    Max {
        into: &'static str,
    },
    /// `into` counts the windows where the column is set.
    Count {
        into: &'static str,
    },
}

/// How a row gives one column's value to the COPY.
pub type CopyValue = for<'a> fn(&'a WindowRow, &'a RowTimes) -> &'a (dyn ToSql + Sync);

/// One column of `windows`.
#[derive(Clone, Copy)]
pub struct Column {
    pub name: &'static str,
    pub sql: SqlType,
    pub nullable: bool,
    pub value: CopyValue,
    /// Kept in `point_latest` (the latest window per point).
    pub latest: bool,
    pub minute: Minute,
}

impl Column {
    const fn new(name: &'static str, sql: SqlType, value: CopyValue) -> Column {
        Column {
            name,
            sql,
            nullable: true,
            value,
            latest: false,
            minute: Minute::None,
        }
    }

    const fn not_null(mut self) -> Column {
        self.nullable = false;
        self
    }

    const fn latest(mut self) -> Column {
        self.latest = true;
        self
    }

    const fn minute(mut self, m: Minute) -> Column {
        self.minute = m;
        self
    }
}

use SqlType::{Bigint, Boolean, Double, Integer, Jsonb, Real, Text, TextArray, Timestamptz};

const fn mean(into: &'static str, max: bool, n: &'static str) -> Minute {
    Minute::Mean { into, max, n }
}

/// The `windows` columns the historian writes, in COPY order (schema versions 1-4).
pub const WINDOWS: &[Column] = &[
    Column::new("point_id", Integer, |r, _| &r.point_id)
        .not_null()
        .latest(),
    Column::new("time", Timestamptz, |r, _| &r.time)
        .not_null()
        .latest(),
    Column::new("window_s", Real, |r, _| &r.window_s).not_null(),
    Column::new("run_start", Timestamptz, |_, t| &t.run_start)
        .not_null()
        .latest(),
    Column::new("seq", Bigint, |_, t| &t.seq)
        .not_null()
        .latest(),
    Column::new("publish_time", Timestamptz, |_, t| &t.publish).not_null(),
    Column::new("state", Text, |r, _| &r.state)
        .not_null()
        .latest(),
    Column::new("state_since", Timestamptz, |r, _| &r.state_since)
        .not_null()
        .latest(),
    Column::new("state_changed", Boolean, |r, _| &r.state_changed).not_null(),
    Column::new("confidence", Real, |r, _| &r.confidence)
        .not_null()
        .latest(),
    Column::new("window_state", Text, |r, _| &r.window_state)
        .not_null()
        .latest(),
    Column::new("unknown_reason", Text, |r, _| &r.unknown_reason),
    Column::new("alarm_despite", Text, |r, _| &r.alarm_despite),
    Column::new("model_id", Integer, |r, _| &r.model_id).not_null(),
    Column::new("p_healthy", Real, |r, _| &r.p[0]),
    Column::new("p_outer_race", Real, |r, _| &r.p[1]),
    Column::new("p_inner_race", Real, |r, _| &r.p[2]),
    Column::new("p_ball", Real, |r, _| &r.p[3]),
    Column::new("p_other", Jsonb, |r, _| &r.p_other),
    Column::new("novelty", Real, |r, _| &r.novelty)
        .not_null()
        .minute(Minute::Max { into: "novelty" }),
    Column::new("novelty_threshold", Real, |r, _| &r.novelty_threshold).not_null(),
    Column::new("baseline_distance", Real, |r, _| &r.baseline_distance),
    Column::new("beyond_baseline", Boolean, |r, _| &r.beyond_baseline),
    Column::new("rpm", Double, |r, _| &r.rpm)
        .latest()
        .minute(mean("rpm", false, "rpm_n")),
    Column::new("speed_source", Text, |r, _| &r.speed_source).not_null(),
    Column::new("velocity_rms_mm_s", Real, |r, _| &r.velocity)
        .latest()
        .minute(mean("velocity", true, "velocity_n")),
    Column::new("iso_zone", Text, |r, _| &r.iso_zone).latest(),
    Column::new("bpfo_1", Real, |r, _| &r.bands[0]).minute(mean("bpfo_1", true, "bands_n")),
    Column::new("bpfo_2", Real, |r, _| &r.bands[1]),
    Column::new("bpfo_3", Real, |r, _| &r.bands[2]),
    Column::new("bpfi_1", Real, |r, _| &r.bands[3]).minute(mean("bpfi_1", true, "bands_n")),
    Column::new("bpfi_2", Real, |r, _| &r.bands[4]),
    Column::new("bpfi_3", Real, |r, _| &r.bands[5]),
    Column::new("two_bsf_1", Real, |r, _| &r.bands[6]).minute(mean("two_bsf_1", true, "bands_n")),
    Column::new("two_bsf_2", Real, |r, _| &r.bands[7]),
    Column::new("two_bsf_3", Real, |r, _| &r.bands[8]),
    Column::new("band_floor", Real, |r, _| &r.band_floor),
    Column::new("quality_ok", Boolean, |r, _| &r.quality_ok)
        .not_null()
        .latest(),
    Column::new("quality_flags", TextArray, |r, _| &r.quality_flags),
    Column::new("clipped_samples", Integer, |r, _| &r.counts[0]).not_null(),
    Column::new("nan_samples", Integer, |r, _| &r.counts[1]).not_null(),
    Column::new("dropout_samples", Integer, |r, _| &r.counts[2]).not_null(),
    Column::new("missing_tacho_pulses", Integer, |r, _| &r.counts[3]).not_null(),
    // schema 2
    Column::new("decision", Text, |r, _| &r.decision).not_null(),
    Column::new("overruled", Text, |r, _| &r.overruled),
    Column::new("evidence_outer_race", Real, |r, _| &r.evidence[0]),
    Column::new("evidence_inner_race", Real, |r, _| &r.evidence[1]),
    Column::new("evidence_ball", Real, |r, _| &r.evidence[2]),
    Column::new("speed_confidence", Real, |r, _| &r.speed_confidence),
    Column::new("speed_rival_rpm", Double, |r, _| &r.speed_rival_rpm),
    Column::new("model_foreign", TextArray, |r, _| &r.model_foreign),
    // schema 3
    Column::new("impulse_beyond_healthy", Real, |r, _| &r.impulse[0]),
    Column::new("impulse_beyond_gaussian", Real, |r, _| &r.impulse[1]),
    // schema 4: the health indicators and the departure test
    Column::new("indicator_rms", Real, |r, _| &r.indicators.values[0]).minute(mean(
        "indicator_rms",
        true,
        "indicators_n",
    )),
    Column::new("indicator_crest", Real, |r, _| &r.indicators.values[1]).minute(mean(
        "indicator_crest",
        true,
        "indicators_n",
    )),
    Column::new("indicator_kurtosis", Real, |r, _| &r.indicators.values[2]).minute(mean(
        "indicator_kurtosis",
        true,
        "indicators_n",
    )),
    Column::new("indicator_resonance", Real, |r, _| &r.indicators.values[3]).minute(mean(
        "indicator_resonance",
        true,
        "indicators_n",
    )),
    Column::new("indicator_samples", Integer, |r, _| &r.indicators.samples),
    Column::new("departure_score_rms", Real, |r, _| &r.indicators.scores[0]),
    Column::new("departure_score_crest", Real, |r, _| {
        &r.indicators.scores[1]
    }),
    Column::new("departure_score_kurtosis", Real, |r, _| {
        &r.indicators.scores[2]
    }),
    Column::new("departure_score_resonance", Real, |r, _| {
        &r.indicators.scores[3]
    }),
    Column::new("departure_smoothed_rms", Real, |r, _| {
        &r.indicators.smoothed[0]
    }),
    Column::new("departure_smoothed_crest", Real, |r, _| {
        &r.indicators.smoothed[1]
    }),
    Column::new("departure_smoothed_kurtosis", Real, |r, _| {
        &r.indicators.smoothed[2]
    }),
    Column::new("departure_smoothed_resonance", Real, |r, _| {
        &r.indicators.smoothed[3]
    }),
    Column::new("departure_threshold_rms", Real, |r, _| {
        &r.indicators.threshold[0]
    }),
    Column::new("departure_threshold_crest", Real, |r, _| {
        &r.indicators.threshold[1]
    }),
    Column::new("departure_threshold_kurtosis", Real, |r, _| {
        &r.indicators.threshold[2]
    }),
    Column::new("departure_threshold_resonance", Real, |r, _| {
        &r.indicators.threshold[3]
    }),
    Column::new("departure_leading", Text, |r, _| &r.indicators.leading),
    Column::new("departure_excess", Real, |r, _| &r.indicators.excess),
    Column::new("departure_beyond_for", Integer, |r, _| {
        &r.indicators.beyond_for
    }),
    Column::new("departed_since", Timestamptz, |r, _| {
        &r.indicators.departed_since
    })
    .minute(Minute::Count {
        into: "departed_windows",
    }),
];

/// The COPY values of one row in [`WINDOWS`] order, then `message` (the staging table's).
pub fn copy_values<'a>(r: &'a WindowRow, t: &'a RowTimes) -> Vec<&'a (dyn ToSql + Sync)> {
    let mut v: Vec<&'a (dyn ToSql + Sync)> = WINDOWS.iter().map(|c| (c.value)(r, t)).collect();
    v.push(&r.message);
    v
}

/// The COPY's types, in [`copy_values`] order.
pub fn copy_types() -> Vec<Type> {
    let mut t: Vec<Type> = WINDOWS.iter().map(|c| c.sql.pg_type()).collect();
    t.push(Type::JSONB);
    t
}

/// `point_id, time, ...`: every column of [`WINDOWS`].
pub fn names() -> String {
    WINDOWS
        .iter()
        .map(|c| c.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// One aggregate column of `minutes`: name, type, the expression over the inserted rows and
/// how a later batch's value is merged into it (`m` = stored, `excluded` = this batch's).
struct Aggregate {
    name: String,
    sql: SqlType,
    nullable: bool,
    expr: String,
    merge: String,
}

fn sum_merge(c: &str) -> String {
    format!("{c} = m.{c} + excluded.{c}")
}

fn max_merge(c: &str) -> String {
    format!("{c} = greatest(m.{c}, excluded.{c})")
}

/// The `minutes` columns [`WINDOWS`] feeds, in table order.
fn aggregates() -> Vec<Aggregate> {
    let mut out: Vec<Aggregate> = Vec::new();
    let mut counted = BTreeSet::new();
    for c in WINDOWS {
        let col = c.name;
        let count = |name: String| Aggregate {
            expr: format!("count({col})"),
            merge: sum_merge(&name),
            sql: Integer,
            nullable: false,
            name,
        };
        let max = |into: &str| Aggregate {
            name: format!("{into}_max"),
            sql: c.sql,
            nullable: true,
            expr: format!("max({col})"),
            merge: max_merge(&format!("{into}_max")),
        };
        match c.minute {
            Minute::None => {}
            Minute::Mean { into, max: m, n } => {
                let sum = format!("{into}_sum");
                out.push(Aggregate {
                    expr: format!("coalesce(sum({col}), 0)"),
                    merge: sum_merge(&sum),
                    sql: Double,
                    nullable: false,
                    name: sum,
                });
                if m {
                    out.push(max(into));
                }
                if counted.insert(n) {
                    out.push(count(n.to_string()));
                }
            }
            Minute::Max { into } => out.push(max(into)),
            Minute::Count { into } => out.push(count(into.to_string())),
        }
    }
    out
}

/// The parts of the `minutes` upsert [`WINDOWS`] feeds: column list, expressions over `ins`
/// and the merges of `ON CONFLICT DO UPDATE`, each comma-separated.
pub fn minute_sql() -> (String, String, String) {
    let a = aggregates();
    let join = |f: fn(&Aggregate) -> String| a.iter().map(f).collect::<Vec<_>>().join(", ");
    (
        join(|a| a.name.clone()),
        join(|a| a.expr.clone()),
        join(|a| a.merge.clone()),
    )
}

/// The `point_latest` columns (column list, and the updates but `point_id`).
pub fn latest_sql() -> (String, String) {
    let cols: Vec<&str> = WINDOWS
        .iter()
        .filter(|c| c.latest)
        .map(|c| c.name)
        .collect();
    let updates: Vec<String> = cols
        .iter()
        .filter(|c| **c != "point_id")
        .map(|c| format!("{c} = excluded.{c}"))
        .collect();
    (cols.join(", "), updates.join(", "))
}

/// What the insert returns for the aggregates: `point_id, time, state, quality_ok` and every
/// column kept in `point_latest` or folded into `minutes`.
pub fn returned() -> String {
    let mut cols = vec!["point_id", "time", "state", "quality_ok"];
    for c in WINDOWS {
        if (c.latest || c.minute != Minute::None) && !cols.contains(&c.name) {
            cols.push(c.name);
        }
    }
    cols.join(", ")
}

/// A column a table must have: name, type, and whether this rigmon may write NULL to it.
struct Expected {
    name: String,
    sql: SqlType,
    nullable: bool,
}

/// The columns `windows`, `minutes` and `point_latest` must have for this rigmon.
fn expected() -> Vec<(&'static str, Vec<Expected>)> {
    let of = |c: &Column| Expected {
        name: c.name.to_string(),
        sql: c.sql,
        nullable: c.nullable,
    };
    let minutes = aggregates()
        .into_iter()
        .map(|a| Expected {
            name: a.name,
            sql: a.sql,
            nullable: a.nullable,
        })
        .collect();
    vec![
        ("windows", WINDOWS.iter().map(of).collect()),
        ("minutes", minutes),
        (
            "point_latest",
            WINDOWS.iter().filter(|c| c.latest).map(of).collect(),
        ),
    ]
}

/// After the migrations: do `windows`, `minutes` and `point_latest` (in the connection's
/// `search_path`) have every column this rigmon writes, with its type, and no NOT NULL where
/// it may write NULL? Columns the database has beyond these are left alone.
pub async fn check(client: &Client, version: i32) -> Result<()> {
    let mut problems = Vec::new();
    for (table, want) in expected() {
        let rows = client
            .query(
                "SELECT a.attname::text, format_type(a.atttypid, a.atttypmod), a.attnotnull
                 FROM pg_attribute a
                 WHERE a.attrelid = to_regclass($1) AND a.attnum > 0 AND NOT a.attisdropped",
                &[&table],
            )
            .await
            .with_context(|| format!("reading the columns of {table}"))?;
        let have: HashMap<String, (String, bool)> = rows
            .iter()
            .map(|r| (r.get(0), (r.get(1), r.get(2))))
            .collect();
        if have.is_empty() {
            problems.push(format!("table {table} is missing"));
            continue;
        }
        for w in want {
            match have.get(&w.name) {
                None => problems.push(format!("{table}.{} is missing", w.name)),
                Some((t, _)) if t != w.sql.name() => {
                    problems.push(format!("{table}.{} is {t}, not {}", w.name, w.sql.name()))
                }
                Some((_, true)) if w.nullable => {
                    problems.push(format!("{table}.{} is NOT NULL but may be empty", w.name))
                }
                Some(_) => {}
            }
        }
    }
    if !problems.is_empty() {
        bail!(
            "the historian's tables do not match schema version {version} ({}): changed by hand or by another program? Restore them, or point [database] at a database (or [database] schema) of its own",
            problems.join("; ")
        );
    }
    Ok(())
}

/// What the history query selects beyond `windows`, as `expression AS name`.
pub const JOINED: &[(&str, &str)] = &[
    ("p.key", "key"),
    ("t.site", "site"),
    ("mo.name", "model_name"),
    ("mo.sha256", "model_sha256"),
    ("mo.labels", "model_labels"),
    ("p.band_channel", "band_channel"),
    ("p.band_orders", "band_orders"),
    ("p.calibration_id", "calibration_id"),
    ("p.software_version", "software_version"),
    ("p.iso_limits_mm_s", "iso_limits_mm_s"),
];

/// `SELECT` of the history query: every [`WINDOWS`] column (as `w.<name>`), then [`JOINED`].
pub fn select() -> String {
    let w = WINDOWS.iter().map(|c| format!("w.{}", c.name));
    let j = JOINED.iter().map(|(e, n)| format!("{e} AS {n}"));
    format!("SELECT {}", w.chain(j).collect::<Vec<_>>().join(", "))
}

/// Position of each name in [`select`], looked up once.
static POSITIONS: LazyLock<HashMap<&'static str, usize>> = LazyLock::new(|| {
    WINDOWS
        .iter()
        .map(|c| c.name)
        .chain(JOINED.iter().map(|j| j.1))
        .enumerate()
        .map(|(i, n)| (n, i))
        .collect()
});

/// One row of [`select`], read by column name.
pub struct Read<'r>(pub &'r Row);

impl Read<'_> {
    /// The value of column `name` (a name [`select`] does not carry is a bug: it panics
    /// naming it, as a wrong type does).
    pub fn get<'a, T: FromSql<'a>>(&'a self, name: &str) -> T {
        let Some(&i) = POSITIONS.get(name) else {
            panic!("the history query selects no column {name}");
        };
        self.0.get(i)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_once_and_the_sql_follows_the_table() {
        assert_eq!(
            POSITIONS.len(),
            WINDOWS.len() + JOINED.len(),
            "names unique"
        );
        let (cols, exprs, _) = minute_sql();
        // one name per aggregate (the expressions and merges hold commas of their own)
        assert_eq!(cols.split(", ").count(), aggregates().len());
        // the schema-1 aggregates, each exactly once
        for c in [
            "rpm_sum",
            "rpm_n",
            "velocity_sum",
            "velocity_max",
            "velocity_n",
            "bpfo_1_sum",
            "bpfo_1_max",
            "bpfi_1_sum",
            "two_bsf_1_max",
            "bands_n",
            "novelty_max",
        ] {
            assert_eq!(cols.split(", ").filter(|x| *x == c).count(), 1, "{c}");
        }
        assert!(exprs.contains("count(bpfo_1)") && !exprs.contains("count(bpfi_1)"));
        let (latest, updates) = latest_sql();
        assert!(latest.starts_with("point_id, time, run_start, seq, state"));
        assert!(!updates.contains("point_id ="));
        let ret = returned();
        for c in [
            "quality_ok",
            "novelty",
            "bpfo_1",
            "indicator_rms",
            "departed_since",
        ] {
            assert!(ret.split(", ").any(|x| x == c), "{c} returned");
        }
    }
}
