//! `rigmon historian --config <historian.toml>`: the fleet historian service (under systemd
//! or by hand). The database is named by `PG*` variables or `[database] url`; the password
//! comes from a file, never from the command line. `--check` refuses a Zenoh setup that
//! could receive nothing (an access-control list in the historian's own config), connects,
//! applies the migrations and exits.

use crate::historian::config::HistorianConfig;
use crate::historian::service::{self, RunOptions};
use crate::historian::{database, migrations, writer::Writer};
use crate::publish::zenoh::ZenohArgs;
use anyhow::Result;
use std::path::PathBuf;

/// Arguments of `rigmon historian`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Historian config file.
    #[arg(long, short, default_value = "config/historian.toml")]
    pub config: PathBuf,
    /// Connect to the database, apply the schema migrations, print what was found, exit.
    #[arg(long)]
    pub check: bool,
    /// Print the last status as JSON on stdout when stopping.
    #[arg(long)]
    pub summary_json: bool,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
}

pub fn run(args: Args) -> Result<()> {
    let mut config = HistorianConfig::load(&args.config)?;
    config.zenoh = args.zenoh.apply(config.zenoh.clone());
    config.validate()?;
    config.zenoh_config()?;
    if args.check {
        let target = config.database.resolve()?;
        let (version, points) = database::block_on(async {
            let (w, version) = Writer::open(&target).await?;
            let n: i64 = w
                .client()
                .query_one("SELECT count(*) FROM points", &[])
                .await?
                .get(0);
            anyhow::Ok((version, n))
        })??;
        println!(
            "ok: database {} schema version {version} (this rigmon writes {}), {points} points; zenoh {} connect {:?}; spill {}",
            target.describe(),
            migrations::latest(),
            config.zenoh.mode,
            config.zenoh.connect,
            config.buffer.spill_dir.display()
        );
        return Ok(());
    }
    let last = service::run(
        config,
        RunOptions {
            use_signals: true,
            ..Default::default()
        },
    )?;
    eprintln!("{}", last.systemd_line());
    if args.summary_json {
        println!("{}", serde_json::to_string(&last)?);
    }
    Ok(())
}
