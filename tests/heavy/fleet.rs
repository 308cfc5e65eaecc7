//! Two sites into one central database, with real parts: three PostgreSQL servers started
//! here (two sites with `wal_level = logical`, one central), a Zenoh router per site in this
//! process (loopback), the built `rigmon historian` per site writing into its own schema
//! (`[database] schema`), and PostgreSQL's own logical replication set up by the shipped
//! `config/fleet/*.sql` through the real `psql`. One site's database is restarted while its
//! points publish; afterwards every window of both sites must be in the central database
//! exactly once, and its 1-minute aggregates must count each window once.

use super::historian::{
    bin, every_field_set, loopback_client, loopback_router, repo, wait_until, Guard, Postgres,
};
use rigmon::historian::status::HistorianStatus;
use std::collections::BTreeMap;
use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::Wait;

const POINTS: usize = 8;

fn now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64
}
const TICKS: u64 = 40;

/// `psql -v ... -f file` against `pg`'s database `db`; panics with its output on failure.
fn psql(pg: &Postgres, db: &str, vars: &[(&str, &str)], file: &Path) {
    let mut c = Command::new("psql");
    c.envs(pg.env(db))
        .args(["-X", "-q", "-v", "ON_ERROR_STOP=1"]);
    for (k, v) in vars {
        c.arg("-v").arg(format!("{k}={v}"));
    }
    let out = c
        .arg("-f")
        .arg(file)
        .output()
        .expect("psql (postgresql-client)");
    assert!(
        out.status.success(),
        "psql -f {} failed: {}{}",
        file.display(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A site's historian config: its router, its schema.
fn site_config(dir: &Path, site: &str, router: &str) -> std::path::PathBuf {
    let cfg = dir.join(format!("{site}.toml"));
    std::fs::write(
        &cfg,
        format!(
            "name = \"{site}\"\ndefault_site = \"{site}\"\nstatus_every_s = 0.3\n\
             [database]\nschema = \"site_{site}\"\n\
             [zenoh]\nmode = \"client\"\nconnect = [\"{router}\"]\nhistory_windows = 0\n\
             [buffer]\nspill_dir = \"spill-{site}\"\n[batch]\nmax_delay_ms = 200\n"
        ),
    )
    .unwrap();
    cfg
}

fn start_historian(dir: &Path, site: &str, cfg: &Path, pg: &Postgres) -> Guard {
    let log = std::fs::File::create(dir.join(format!("{site}.log"))).unwrap();
    let c = Command::new(bin())
        .args(["historian", "--config", cfg.to_str().unwrap()])
        .envs(pg.env("fleet"))
        .env("RUST_LOG", "info")
        .stdout(Stdio::null())
        .stderr(log)
        .spawn()
        .unwrap();
    Guard(c)
}

/// The historian `name`'s last status, kept as it arrives.
fn status_of(
    client: &zenoh::Session,
    name: &str,
) -> (
    zenoh::pubsub::Subscriber<()>,
    Arc<Mutex<Option<HistorianStatus>>>,
) {
    let status: Arc<Mutex<Option<HistorianStatus>>> = Arc::default();
    let s2 = status.clone();
    let sub = client
        .declare_subscriber(format!("rigmon/@historian/{name}/status"))
        .callback(move |s| {
            *s2.lock().unwrap() = serde_json::from_slice(&s.payload().to_bytes()).ok()
        })
        .wait()
        .unwrap();
    (sub, status)
}

/// Window `seq` of point `i` of `site`, published now.
fn message(site: &str, i: usize, seq: u64, run_ns: u64) -> Vec<u8> {
    let mut m = every_field_set(run_ns, seq);
    m.rig = format!("{site}-{i}");
    m.site = Some(site.to_string());
    m.state_changed = seq == 1;
    m.publish_time_ns = now_ns();
    serde_json::to_vec(&m).unwrap()
}

/// (key, seq) -> how many times, in `schema` of the central database.
fn central_windows(central: &Postgres, schema: &str) -> BTreeMap<(String, i64), i64> {
    let (rt, c) = central.client("central");
    let rows = rt
        .block_on(c.query(
            &format!(
                "SELECT p.key, w.seq, count(*) FROM {schema}.windows w
                 JOIN {schema}.points p USING (point_id) GROUP BY 1, 2"
            ),
            &[],
        ))
        .unwrap();
    rows.iter()
        .map(|r| ((r.get(0), r.get(1)), r.get(2)))
        .collect()
}

fn central_count(central: &Postgres, schema: &str) -> i64 {
    let (rt, c) = central.client("central");
    rt.block_on(c.query_one(&format!("SELECT count(*) FROM {schema}.windows"), &[]))
        .map(|r| r.get(0))
        .unwrap_or(0)
}

#[test]
fn two_sites_replicate_every_window_exactly_once_into_one_central_database() {
    let dir = tempfile::tempdir().unwrap();
    let sites = ["north", "south"];
    let site_pg: Vec<Postgres> = sites
        .iter()
        .map(|_| Postgres::start_with("-c wal_level=logical"))
        .collect();
    let central = Postgres::start_with("");
    for pg in &site_pg {
        let (rt, c) = pg.client("postgres");
        rt.block_on(c.batch_execute("CREATE DATABASE fleet"))
            .unwrap();
    }
    let (rt, c) = central.client("postgres");
    rt.block_on(c.batch_execute("CREATE DATABASE central"))
        .unwrap();
    drop((c, rt));
    // The central server's own pgpass for the sites (its OS user's, mode 0600).
    let passfile = dir.path().join("sites.pgpass");
    let lines: String = site_pg.iter().map(|pg| pg.pgpass_line()).collect();
    std::fs::write(&passfile, lines).unwrap();
    std::fs::set_permissions(&passfile, std::fs::Permissions::from_mode(0o600)).unwrap();
    Command::new("chown")
        .args(["postgres:postgres"])
        .arg(&passfile)
        .status()
        .unwrap();
    std::fs::set_permissions(dir.path(), std::fs::Permissions::from_mode(0o755)).unwrap();

    let routers: Vec<(String, zenoh::Session)> = sites.iter().map(|_| loopback_router()).collect();
    let mut historians = Vec::new();
    let mut watchers = Vec::new();
    for (k, site) in sites.iter().enumerate() {
        let cfg = site_config(dir.path(), site, &routers[k].0);
        // The central copy of the site's schema: made by the historian's own migrations.
        let check = Command::new(bin())
            .args(["historian", "--check", "--config", cfg.to_str().unwrap()])
            .envs(central.env("central"))
            .output()
            .unwrap();
        assert!(
            check.status.success(),
            "{}",
            String::from_utf8_lossy(&check.stderr)
        );
        historians.push(start_historian(dir.path(), site, &cfg, &site_pg[k]));
        let client = loopback_client(&routers[k].0);
        let (sub, status) = status_of(&client, site);
        wait_until(
            &format!("{site}'s historian connected"),
            Duration::from_secs(60),
            || {
                status
                    .lock()
                    .unwrap()
                    .as_ref()
                    .is_some_and(|s| s.database.connected)
            },
        );
        let schema = format!("site_{site}");
        psql(
            &site_pg[k],
            "fleet",
            &[("schema", &schema)],
            &repo().join("config/fleet/site-publication.sql"),
        );
        let conninfo = format!(
            "host=127.0.0.1 port={} dbname=fleet user=rigmon passfile={}",
            site_pg[k].port(),
            passfile.display()
        );
        psql(
            &central,
            "central",
            &[("schema", &schema), ("conninfo", &conninfo)],
            &repo().join("config/fleet/central-subscription.sql"),
        );
        watchers.push((client, sub, status));
    }

    // Publish; restart the north site's database a third of the way through.
    let run_ns = now_ns() - 10_000_000_000;
    let pubs: Vec<Vec<zenoh::pubsub::Publisher>> = sites
        .iter()
        .enumerate()
        .map(|(k, site)| {
            (0..POINTS)
                .map(|i| {
                    watchers[k]
                        .0
                        .declare_publisher(format!("rigmon/{site}-{i}/shaft/nde/health"))
                        .wait()
                        .unwrap()
                })
                .collect()
        })
        .collect();
    for p in pubs.iter().map(|p| &p[0]) {
        wait_until(
            "the historian's subscription",
            Duration::from_secs(20),
            || p.matching_status().wait().is_ok_and(|m| m.matching()),
        );
    }
    let t0 = Instant::now();
    for seq in 1..=TICKS {
        if seq == TICKS / 3 {
            site_pg[0].restart();
        }
        for (k, site) in sites.iter().enumerate() {
            for (i, p) in pubs[k].iter().enumerate() {
                p.put(message(site, i, seq, run_ns)).wait().unwrap();
            }
        }
        let due = Duration::from_millis(250 * seq);
        std::thread::sleep(due.saturating_sub(t0.elapsed()));
    }

    let published = (POINTS as u64 * TICKS) as i64;
    for site in sites {
        let schema = format!("site_{site}");
        wait_until(
            &format!("{published} windows of {site} in the central database"),
            Duration::from_secs(120),
            || central_count(&central, &schema) >= published,
        );
    }
    // Let anything that would arrive twice arrive.
    std::thread::sleep(Duration::from_secs(3));
    for (k, site) in sites.iter().enumerate() {
        let schema = format!("site_{site}");
        let got = central_windows(&central, &schema);
        let mut want = BTreeMap::new();
        for i in 0..POINTS {
            for seq in 1..=TICKS {
                want.insert((format!("{site}-{i}/shaft/nde"), seq as i64), 1i64);
            }
        }
        assert_eq!(got, want, "{site}: every window exactly once centrally");
        let (rt, c) = central.client("central");
        let minutes: i64 = rt
            .block_on(c.query_one(
                &format!("SELECT sum(windows)::int8 FROM {schema}.minutes"),
                &[],
            ))
            .unwrap()
            .get(0);
        assert_eq!(
            minutes, published,
            "{site}: each window counted once in minutes"
        );
        let st = watchers[k].2.lock().unwrap().clone().unwrap();
        assert_eq!(st.lost.windows, 0, "{site}: {:?}", st.lost);
        if k == 0 {
            assert!(
                st.database.reconnects >= 1,
                "north's historian saw its database restart: {:?}",
                st.database
            );
        }
    }
    drop(historians);
}
