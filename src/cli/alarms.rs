//! `rigmon alarms` lists the historian's state-change events (newest first) and `rigmon ack
//! <id> --user NAME --comment TEXT` acknowledges one. Both read the database the way psql
//! does (`PG*` variables, `PGPASSFILE`), or as a historian config names it (`--config`).

use crate::historian::alarms::{self, Filter};
use crate::historian::config::HistorianConfig;
use crate::historian::database::{self, DatabaseSettings};
use crate::publish::time_range::parse_duration;
use anyhow::Result;
use std::path::PathBuf;
use std::time::SystemTime;

/// Where the database is.
#[derive(clap::Args, Debug, Clone)]
pub struct DbArgs {
    /// Take `[database]` from this historian config (else the PG* variables alone).
    #[arg(long, value_name = "TOML")]
    pub config: Option<PathBuf>,
    /// A postgresql:// URL without password (the password comes from PGPASSFILE).
    #[arg(long, value_name = "URL")]
    pub db: Option<String>,
}

impl DbArgs {
    fn settings(&self) -> Result<DatabaseSettings> {
        let mut s = match &self.config {
            Some(p) => HistorianConfig::load(p)?.database,
            None => DatabaseSettings::default(),
        };
        if let Some(u) = &self.db {
            s.url = Some(u.clone());
        }
        s.validate()?;
        Ok(s)
    }
}

/// Arguments of `rigmon alarms`.
#[derive(clap::Args, Debug)]
pub struct ListArgs {
    /// Only events of the last DURATION (e.g. 24h, 7d).
    #[arg(long, value_name = "DURATION")]
    pub since: Option<String>,
    /// Only events nobody acknowledged yet.
    #[arg(long)]
    pub unacked: bool,
    /// Only points matching this pattern (`*` wildcards), e.g. `lut-rig/*`.
    #[arg(long)]
    pub point: Option<String>,
    /// At most this many events.
    #[arg(long, default_value_t = 100)]
    pub limit: i64,
    /// One JSON object per line.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub db: DbArgs,
}

/// Arguments of `rigmon ack`.
#[derive(clap::Args, Debug)]
pub struct AckArgs {
    /// The event id (first column of `rigmon alarms`).
    pub id: i64,
    /// Who acknowledges (default: $USER).
    #[arg(long)]
    pub user: Option<String>,
    /// Why, what was done.
    #[arg(long, default_value = "")]
    pub comment: String,
    #[command(flatten)]
    pub db: DbArgs,
}

pub fn list(args: ListArgs) -> Result<()> {
    let target = args.db.settings()?.resolve()?;
    let since = args
        .since
        .as_deref()
        .map(parse_duration)
        .transpose()?
        .map(|d| SystemTime::now() - d);
    let filter = Filter {
        since,
        unacked_only: args.unacked,
        point: args.point.clone(),
        limit: args.limit.max(1),
    };
    let found = database::block_on(async {
        let c = target.connect().await?;
        alarms::list(&c, &filter).await
    })??;
    for a in &found {
        if args.json {
            println!("{}", serde_json::to_string(a)?);
        } else {
            println!("{}", alarms::line(a));
        }
    }
    if found.is_empty() && !args.json {
        eprintln!("no events in {} for these filters", target.describe());
    }
    Ok(())
}

pub fn ack(args: AckArgs) -> Result<()> {
    let target = args.db.settings()?.resolve()?;
    let user = args
        .user
        .clone()
        .or_else(|| std::env::var("USER").ok())
        .unwrap_or_default();
    let a = database::block_on(async {
        let c = target.connect().await?;
        alarms::ack(&c, args.id, &user, &args.comment).await
    })??;
    println!("{}", alarms::line(&a));
    Ok(())
}
