//! Time partitions: `windows` by day (`windows_p20261126`), `minutes` by month
//! (`minutes_p202611`), made on demand before a batch that needs them, and dropped whole once
//! they are past their retention (`[retention] windows_days`, `minutes_days`): dropping a
//! partition is instant and leaves no bloat, unlike `DELETE`.

use anyhow::{Context, Result};
use std::collections::HashSet;
use std::time::{Duration, SystemTime, UNIX_EPOCH};
use tokio_postgres::Client;

const DAY_S: u64 = 86_400;

/// A civil date (UTC).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Day {
    pub year: i32,
    pub month: u32,
    pub day: u32,
}

impl Day {
    /// The UTC date of `t`.
    pub fn of(t: SystemTime) -> Day {
        let secs = t
            .duration_since(UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0);
        let text = humantime::format_rfc3339_seconds(
            UNIX_EPOCH + Duration::from_secs(secs - secs % DAY_S),
        )
        .to_string();
        Day {
            year: text[0..4].parse().unwrap_or(1970),
            month: text[5..7].parse().unwrap_or(1),
            day: text[8..10].parse().unwrap_or(1),
        }
    }

    fn start(&self) -> SystemTime {
        humantime::parse_rfc3339(&format!(
            "{:04}-{:02}-{:02}T00:00:00Z",
            self.year, self.month, self.day
        ))
        .unwrap_or(UNIX_EPOCH)
    }

    fn next(&self) -> Day {
        Day::of(self.start() + Duration::from_secs(DAY_S))
    }

    fn month_start(&self) -> Day {
        Day { day: 1, ..*self }
    }

    fn next_month(&self) -> Day {
        let (year, month) = if self.month == 12 {
            (self.year + 1, 1)
        } else {
            (self.year, self.month + 1)
        };
        Day {
            year,
            month,
            day: 1,
        }
    }

    fn sql(&self) -> String {
        format!(
            "{:04}-{:02}-{:02} 00:00:00+00",
            self.year, self.month, self.day
        )
    }

    /// `windows_pYYYYMMDD` / `minutes_pYYYYMM` back to the date they start on.
    fn from_partition(name: &str) -> Option<(String, Day)> {
        let (table, stamp) = name.split_once("_p")?;
        let year = stamp.get(0..4)?.parse().ok()?;
        let month = stamp.get(4..6)?.parse().ok()?;
        let day = match stamp.len() {
            8 => stamp.get(6..8)?.parse().ok()?,
            6 => 1,
            _ => return None,
        };
        Some((table.to_string(), Day { year, month, day }))
    }
}

/// The partitions known to exist (so each is created once per historian run).
#[derive(Debug, Default)]
pub struct Partitions {
    known: HashSet<String>,
}

impl Partitions {
    /// Make sure the daily `windows` and monthly `minutes` partitions holding `times` exist.
    pub async fn ensure(
        &mut self,
        client: &Client,
        times: impl Iterator<Item = SystemTime>,
    ) -> Result<()> {
        let days: HashSet<Day> = times.map(Day::of).collect();
        for d in days {
            let w = format!("windows_p{:04}{:02}{:02}", d.year, d.month, d.day);
            if !self.known.contains(&w) {
                create(client, &w, "windows", &d, &d.next()).await?;
                self.known.insert(w);
            }
            let m0 = d.month_start();
            let m = format!("minutes_p{:04}{:02}", m0.year, m0.month);
            if !self.known.contains(&m) {
                create(client, &m, "minutes", &m0, &m0.next_month()).await?;
                self.known.insert(m);
            }
        }
        Ok(())
    }

    /// Forget what is known (after a reconnect the database may have changed).
    pub fn forget(&mut self) {
        self.known.clear();
    }
}

async fn create(client: &Client, name: &str, parent: &str, from: &Day, to: &Day) -> Result<()> {
    let sql = format!(
        "CREATE TABLE IF NOT EXISTS {name} PARTITION OF {parent} FOR VALUES FROM ('{}') TO ('{}')",
        from.sql(),
        to.sql()
    );
    match client.batch_execute(&sql).await {
        Ok(()) => Ok(()),
        // Another historian made it between our IF NOT EXISTS check and the create.
        Err(e) if e.code() == Some(&tokio_postgres::error::SqlState::DUPLICATE_TABLE) => Ok(()),
        Err(e) => Err(e).with_context(|| format!("creating partition {name}")),
    }
}

/// Drop the partitions wholly older than the retention; returns their names.
pub async fn apply_retention(
    client: &Client,
    windows_days: u32,
    minutes_days: u32,
    now: SystemTime,
) -> Result<Vec<String>> {
    let rows = client
        .query(
            "SELECT c.relname, p.relname FROM pg_inherits i
             JOIN pg_class c ON c.oid = i.inhrelid JOIN pg_class p ON p.oid = i.inhparent
             WHERE p.relname IN ('windows', 'minutes')
               AND p.relnamespace = current_schema()::regnamespace",
            &[],
        )
        .await
        .context("listing partitions")?;
    let mut dropped = Vec::new();
    for r in rows {
        let name: String = r.get(0);
        let Some((table, start)) = Day::from_partition(&name) else {
            continue;
        };
        let (end, keep_days) = match table.as_str() {
            "windows" => (start.next(), windows_days),
            "minutes" => (start.next_month(), minutes_days),
            _ => continue,
        };
        let horizon = now - Duration::from_secs(u64::from(keep_days) * DAY_S);
        if end.start() <= horizon {
            client
                .batch_execute(&format!("DROP TABLE IF EXISTS {name}"))
                .await
                .with_context(|| format!("dropping partition {name} (retention)"))?;
            tracing::info!("retention: dropped partition {name}");
            dropped.push(name);
        }
    }
    Ok(dropped)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn days_months_and_partition_names() {
        let t = humantime::parse_rfc3339("2026-12-31T23:59:59Z").unwrap();
        let d = Day::of(t);
        assert_eq!((d.year, d.month, d.day), (2026, 12, 31));
        assert_eq!(
            d.next(),
            Day {
                year: 2027,
                month: 1,
                day: 1
            }
        );
        assert_eq!(
            d.next_month(),
            Day {
                year: 2027,
                month: 1,
                day: 1
            }
        );
        assert_eq!(
            Day::from_partition("windows_p20261231"),
            Some(("windows".into(), d))
        );
        assert_eq!(
            Day::from_partition("minutes_p202612"),
            Some(("minutes".into(), d.month_start()))
        );
        assert_eq!(Day::from_partition("points"), None);
    }
}
