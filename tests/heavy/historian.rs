//! The fleet historian end to end, with real parts: a PostgreSQL server started here (initdb
//! and pg_ctl in a temporary folder, loopback only, password authentication with the password
//! in a pgpass file), a Zenoh router in this process (loopback, multicast scouting off), three
//! built `rigmon run` daemons replaying different recordings (the LUT rig's simulated outer
//! race, CWRU drive end and fan end), and the built `rigmon historian`, `history`, `alarms`
//! and `ack`. The database is killed for 30 s and the historian killed and restarted mid-run;
//! every window must end up in the database exactly once. Also: the Grafana provisioning
//! parses and its queries run on the real database, the systemd unit verifies, and bad
//! database settings are refused at start. And: a health message with every field set goes
//! through the historian into a database that started at schema version 1 (migrated in place)
//! and comes back over `rigmon history` field for field.

use rigmon::historian::status::HistorianStatus;
use rigmon::publish::zenoh::ZenohSettings;
use std::collections::{BTreeMap, BTreeSet};
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::Wait;

pub(crate) fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub(crate) fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_rigmon")
}

pub(crate) fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Kills a child when dropped (a failing assertion must not leave processes behind).
pub(crate) struct Guard(pub(crate) Child);
impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Wait for `cond`, polling; panics naming `what` at the deadline.
pub(crate) fn wait_until(what: &str, timeout: Duration, mut cond: impl FnMut() -> bool) {
    let t = Instant::now();
    while !cond() {
        assert!(
            t.elapsed() < timeout,
            "timed out after {timeout:?} waiting for {what}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// A throwaway PostgreSQL server: its own folder, port and superuser `rigmon` with a password.
pub(crate) struct Postgres {
    dir: tempfile::TempDir,
    bin: PathBuf,
    port: u16,
    password: String,
    passfile: PathBuf,
    /// Extra server options (`-c name=value ...`).
    opts: String,
}

fn postgres_bin() -> PathBuf {
    let mut found: Vec<PathBuf> = std::fs::read_dir("/usr/lib/postgresql")
        .expect("PostgreSQL is needed: apt-get install postgresql (.ci/run does)")
        .filter_map(|e| e.ok().map(|e| e.path().join("bin")))
        .filter(|p| p.join("initdb").is_file())
        .collect();
    found.sort_by_key(|p| {
        p.parent()
            .and_then(|v| v.file_name())
            .and_then(|v| v.to_str())
            .and_then(|v| v.parse::<u32>().ok())
    });
    found
        .pop()
        .expect("no /usr/lib/postgresql/*/bin/initdb: apt-get install postgresql")
}

fn as_postgres(args: &[&str]) -> Output {
    let out = Command::new("runuser")
        .args(["-u", "postgres", "--"])
        .args(args)
        .output()
        .expect("runuser (util-linux)");
    assert!(
        out.status.success(),
        "{args:?} failed: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

impl Postgres {
    fn start() -> Postgres {
        Postgres::start_with("")
    }

    /// A server started with extra options, e.g. `-c wal_level=logical`.
    pub(crate) fn start_with(opts: &str) -> Postgres {
        let bin = postgres_bin();
        let dir = tempfile::tempdir().unwrap();
        let password = format!("pw-{}-{}", std::process::id(), free_port());
        let pwfile = dir.path().join("initpw");
        std::fs::write(&pwfile, format!("{password}\n")).unwrap();
        Command::new("chown")
            .args(["-R", "postgres:postgres"])
            .arg(dir.path())
            .status()
            .unwrap();
        let data = dir.path().join("data");
        let initdb = bin.join("initdb");
        as_postgres(&[
            initdb.to_str().unwrap(),
            "-D",
            data.to_str().unwrap(),
            "-U",
            "rigmon",
            "--auth=scram-sha-256",
            "--pwfile",
            pwfile.to_str().unwrap(),
            "-E",
            "UTF8",
            "--locale=C",
        ]);
        std::fs::remove_file(&pwfile).unwrap();
        // The client side's pgpass, root's own, mode 0600 as libpq wants it.
        let passfile = dir.path().join("client.pgpass");
        let port = free_port();
        std::fs::write(&passfile, format!("127.0.0.1:{port}:*:rigmon:{password}\n")).unwrap();
        std::fs::set_permissions(&passfile, std::fs::Permissions::from_mode(0o600)).unwrap();
        let pg = Postgres {
            dir,
            bin,
            port,
            password,
            passfile,
            opts: opts.to_string(),
        };
        pg.start_server();
        pg
    }

    fn start_server(&self) {
        let d = self.dir.path();
        as_postgres(&[
            self.bin.join("pg_ctl").to_str().unwrap(),
            "-D",
            d.join("data").to_str().unwrap(),
            "-w",
            "-l",
            d.join("pg.log").to_str().unwrap(),
            "-o",
            &format!(
                "-p {} -k {} -c listen_addresses=127.0.0.1 {}",
                self.port,
                d.display(),
                self.opts
            ),
            "start",
        ]);
    }

    pub(crate) fn port(&self) -> u16 {
        self.port
    }

    /// This server's line for a pgpass file (user `rigmon`, any database).
    pub(crate) fn pgpass_line(&self) -> String {
        format!("127.0.0.1:{}:*:rigmon:{}\n", self.port, self.password)
    }

    /// Stop the server cleanly (`-m fast`: sessions ended, WAL flushed) and start it again.
    pub(crate) fn restart(&self) {
        as_postgres(&[
            self.bin.join("pg_ctl").to_str().unwrap(),
            "-D",
            self.dir.path().join("data").to_str().unwrap(),
            "-m",
            "fast",
            "stop",
        ]);
        self.start_server();
    }

    /// Kill the server the hard way (no shutdown checkpoint), as a crash would.
    fn kill(&self) {
        as_postgres(&[
            self.bin.join("pg_ctl").to_str().unwrap(),
            "-D",
            self.dir.path().join("data").to_str().unwrap(),
            "-m",
            "immediate",
            "stop",
        ]);
    }

    pub(crate) fn env(&self, db: &str) -> Vec<(String, String)> {
        vec![
            ("PGHOST".into(), "127.0.0.1".into()),
            ("PGPORT".into(), self.port.to_string()),
            ("PGUSER".into(), "rigmon".into()),
            ("PGDATABASE".into(), db.into()),
            ("PGPASSFILE".into(), self.passfile.display().to_string()),
        ]
    }

    pub(crate) fn client(&self, db: &str) -> (tokio::runtime::Runtime, tokio_postgres::Client) {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        let conn = format!(
            "host=127.0.0.1 port={} user=rigmon dbname={db} password={}",
            self.port, self.password
        );
        let client = rt.block_on(async {
            let (c, connection) = tokio_postgres::connect(&conn, tokio_postgres::NoTls)
                .await
                .unwrap();
            tokio::spawn(connection);
            c
        });
        (rt, client)
    }
}

impl Postgres {
    /// A server with an empty `fleet` database, as the historian's config names it.
    pub(crate) fn with_fleet_database() -> Postgres {
        let pg = Postgres::start();
        let (rt, c) = pg.client("postgres");
        rt.block_on(c.batch_execute("CREATE DATABASE fleet"))
            .unwrap();
        drop((c, rt));
        pg
    }
}

impl Drop for Postgres {
    fn drop(&mut self) {
        let _ = Command::new("runuser")
            .args(["-u", "postgres", "--"])
            .arg(self.bin.join("pg_ctl"))
            .args([
                "-D",
                self.dir.path().join("data").to_str().unwrap(),
                "-m",
                "immediate",
                "stop",
            ])
            .output();
    }
}

/// A daemon config replaying `file` in real time, looping, as a Zenoh client of the router.
/// A Zenoh router in this process on a free loopback port (multicast scouting off, as every
/// [`ZenohSettings`] has it), and its endpoint.
pub(crate) fn loopback_router() -> (String, zenoh::Session) {
    let router_ep = format!("tcp/127.0.0.1:{}", free_port());
    let router = ZenohSettings {
        mode: rigmon::vocabulary::ZenohMode::Router,
        listen: vec![router_ep.clone()],
        ..Default::default()
    }
    .open()
    .unwrap();
    (router_ep, router)
}

/// A client session of that router.
pub(crate) fn loopback_client(router_ep: &str) -> zenoh::Session {
    ZenohSettings {
        mode: rigmon::vocabulary::ZenohMode::Client,
        connect: vec![router_ep.to_string()],
        ..Default::default()
    }
    .open()
    .unwrap()
}

/// The test historian's last status (`rigmon/@historian/test/status`), kept as it arrives;
/// the subscriber must stay alive as long as it is read.
pub(crate) fn historian_status(
    client: &zenoh::Session,
) -> (
    zenoh::pubsub::Subscriber<()>,
    Arc<Mutex<Option<HistorianStatus>>>,
) {
    let status: Arc<Mutex<Option<HistorianStatus>>> = Arc::default();
    let s2 = status.clone();
    let sub = client
        .declare_subscriber("rigmon/@historian/test/status")
        .callback(move |s| {
            *s2.lock().unwrap() = serde_json::from_slice(&s.payload().to_bytes()).ok()
        })
        .wait()
        .unwrap();
    (sub, status)
}

fn daemon(dir: &Path, name: &str, rig: &Path, model: &str, file: &Path, router: &str) -> Guard {
    let cfg = dir.join(format!("{name}.toml"));
    std::fs::write(
        &cfg,
        format!(
            "rig = {rig:?}\n[model]\npath = {:?}\n[source]\ntype = \"file\"\npath = {file:?}\nspeed = 1.0\nloop = true\n\
             [pipeline]\nspectrum = false\nstatus_every_s = 1.0\n\
             [zenoh]\nmode = \"client\"\nconnect = [\"{router}\"]\nhistory_windows = 1200\n",
            repo().join("models").join(model),
        ),
    )
    .unwrap();
    let c = Command::new(bin())
        .args(["run", "--config", cfg.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.join(format!("{name}.log"))).unwrap())
        .spawn()
        .unwrap();
    Guard(c)
}

fn historian(dir: &Path, pg: &Postgres, router: &str) -> Guard {
    let cfg = dir.join("historian.toml");
    std::fs::write(
        &cfg,
        format!(
            "name = \"test\"\ndefault_site = \"plant\"\nstatus_every_s = 0.3\n\
             [zenoh]\nmode = \"client\"\nconnect = [\"{router}\"]\nhistory_windows = 0\n\
             [buffer]\nmemory_messages = 20\nspill_dir = \"spill\"\n\
             [batch]\nmax_delay_ms = 200\n[recovery]\nquery_timeout_s = 5.0\n"
        ),
    )
    .unwrap();
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(dir.join("historian.log"))
        .unwrap();
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

fn rigmon(args: &[&str], env: &[(String, String)]) -> Output {
    Command::new(bin())
        .args(args)
        .envs(env.iter().cloned())
        .output()
        .unwrap()
}

/// Every health message seen on the router: address -> seq -> state_changed.
type Truth = Arc<Mutex<BTreeMap<String, BTreeMap<u64, bool>>>>;

#[test]
fn three_daemons_a_router_and_the_historian_keep_every_window_once_through_outages() {
    let data = repo().join("../shared/data");
    assert!(
        data.join("cwru/97_Normal_0.mat").is_file(),
        "../shared/data must sit beside the checkout"
    );
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let pg = Postgres::with_fleet_database();
    let (router_ep, router) = loopback_router();
    let client = loopback_client(&router_ep);
    let truth: Truth = Arc::default();
    let t2 = truth.clone();
    let _truth_sub = client
        .declare_subscriber("rigmon/**/health")
        .callback(move |s| {
            let v: serde_json::Value = serde_json::from_slice(&s.payload().to_bytes()).unwrap();
            let addr = format!(
                "{}/{}/{}",
                v["rig"].as_str().unwrap(),
                v["asset"].as_str().unwrap(),
                v["point"].as_str().unwrap()
            );
            t2.lock().unwrap().entry(addr).or_default().insert(
                v["seq"].as_u64().unwrap(),
                v["state_changed"].as_bool().unwrap(),
            );
        })
        .wait()
        .unwrap();
    let (_status_sub, status) = historian_status(&client);
    let st = || status.lock().unwrap().clone();
    let mut hist = historian(d, &pg, &router_ep);
    wait_until(
        "the historian's status with its database connected",
        Duration::from_secs(60),
        || st().is_some_and(|s| s.database.connected),
    );
    let cmdline = std::fs::read(format!("/proc/{}/cmdline", hist.0.id())).unwrap();
    assert!(
        !String::from_utf8_lossy(&cmdline).contains(&pg.password),
        "password on the command line"
    );

    // Three machines: the LUT rig (its rig file names a site), CWRU drive end and fan end.
    let lut_rig = d.join("lut-rig.toml");
    let text = std::fs::read_to_string(repo().join("config/lut-rig.toml")).unwrap();
    std::fs::write(
        &lut_rig,
        text.replacen("point = \"nde\"", "point = \"nde\"\nsite = \"lut-lab\"", 1),
    )
    .unwrap();
    let mut daemons = vec![
        daemon(
            d,
            "lut",
            &lut_rig,
            "lut-rig.onnx",
            &repo().join("replay/lut-outer_race-588rpm.mcap"),
            &router_ep,
        ),
        daemon(
            d,
            "de",
            &repo().join("config/cwru-de.toml"),
            "cwru-de.onnx",
            &data.join("cwru/12k_Drive_End_Bearing_Fault_Data/OR/007/@6/130@6_0.mat"),
            &router_ep,
        ),
        daemon(
            d,
            "fe",
            &repo().join("config/cwru-fe.toml"),
            "cwru-fe.onnx",
            &data.join("cwru-fe/007/IR007_1.mat"),
            &router_ep,
        ),
    ];
    let points = ["lut-rig/shaft/nde", "cwru-de/motor/de", "cwru-fe/motor/fe"];
    let (rt, db) = pg.client("fleet");
    let per_point = |sql: &str| -> BTreeMap<String, i64> {
        rt.block_on(db.query(sql, &[]))
            .unwrap()
            .iter()
            .map(|r| (r.get::<_, String>(0), r.get::<_, i64>(1)))
            .collect()
    };
    let rows = || {
        per_point("SELECT p.key, count(*) FROM windows JOIN points p USING (point_id) GROUP BY 1")
    };
    wait_until(
        "10 windows of each daemon in the database",
        Duration::from_secs(120),
        || {
            let r = rows();
            points.iter().all(|p| r.get(*p).copied().unwrap_or(0) >= 10)
        },
    );

    // The database killed for 30 s: the historian buffers (memory, then the spill) and catches up.
    pg.kill();
    wait_until(
        "the historian to see the database down",
        Duration::from_secs(20),
        || st().is_some_and(|s| !s.database.connected),
    );
    std::thread::sleep(Duration::from_secs(30));
    let during = st().unwrap();
    assert!(
        during.buffer.spilled_total > 0,
        "30 s down with a 20-message memory buffer must spill: {during:?}"
    );
    pg.start_server();
    wait_until(
        "the historian to catch up after the database came back",
        Duration::from_secs(90),
        || {
            st().is_some_and(|s| {
                s.database.connected
                    && s.buffer.memory == 0
                    && s.buffer.spilled == 0
                    && s.database.reconnects > 0
            })
        },
    );
    let (rt, db) = pg.client("fleet");
    let rows = || -> BTreeMap<String, i64> {
        rt.block_on(db.query(
            "SELECT p.key, count(*) FROM windows JOIN points p USING (point_id) GROUP BY 1",
            &[],
        ))
        .unwrap()
        .iter()
        .map(|r| (r.get::<_, String>(0), r.get::<_, i64>(1)))
        .collect()
    };

    // The historian killed (no chance to flush) and restarted 8 s later: it asks the daemons
    // for what it missed. All three kept publishing meanwhile, so it finds a gap for each, and
    // the daemons stay up until every window asked for is answered (recovered or lost): a
    // daemon stopped while its answer is on the way would lose windows the test then misses.
    hist.0.kill().unwrap();
    hist.0.wait().unwrap();
    *status.lock().unwrap() = None;
    std::thread::sleep(Duration::from_secs(8));
    let hist = historian(d, &pg, &router_ep);
    wait_until(
        "the restarted historian to recover what it missed",
        Duration::from_secs(90),
        || {
            st().is_some_and(|s| {
                s.database.connected
                    && s.recovery.gaps >= points.len() as u64
                    && s.recovery.recovered > 0
                    && s.recovery.waiting + s.recovery.in_flight == 0
                    && s.recovery.recovered + s.recovery.lost + s.recovery.late
                        >= s.recovery.requested
                    && s.buffer.memory == 0
                    && s.buffer.spilled == 0
            })
        },
    );

    // Stop the daemons; everything they published must arrive.
    for g in &daemons {
        unsafe { libc::kill(g.0.id() as i32, libc::SIGTERM) };
    }
    for g in daemons.iter_mut() {
        let t = Instant::now();
        while g.0.try_wait().unwrap().is_none() {
            assert!(t.elapsed() < Duration::from_secs(30), "daemon did not stop");
            std::thread::sleep(Duration::from_millis(50));
        }
    }
    let seen: BTreeMap<String, BTreeMap<u64, bool>> = truth.lock().unwrap().clone();
    for p in points {
        assert!(
            seen.get(p).is_some_and(|s| s.len() >= 40),
            "{p}: the router saw too little: {:?}",
            seen.get(p).map(|s| s.len())
        );
    }
    let t = Instant::now();
    loop {
        let r = rows();
        if points
            .iter()
            .all(|p| r.get(*p).copied().unwrap_or(0) as usize >= seen[*p].len())
        {
            break;
        }
        if t.elapsed() > Duration::from_secs(60) {
            let log = std::fs::read_to_string(d.join("historian.log")).unwrap_or_default();
            let tail: Vec<&str> = log.lines().rev().take(40).collect();
            let want: Vec<(String, usize, Option<u64>)> = seen
                .iter()
                .map(|(k, v)| (k.clone(), v.len(), v.keys().last().copied()))
                .collect();
            let missing: Vec<(&str, Vec<u64>)> = points
                .iter()
                .map(|p| (*p, seen_not_stored(&rt, &db, p, &seen[*p])))
                .collect();
            panic!("not every window the router saw is in the database: {r:?} vs {want:?}\nmissing {missing:?}\nstatus {:?}\nlog tail:\n{}", st(), tail.join("\n"));
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    wait_until(
        "the historian's buffer empty",
        Duration::from_secs(30),
        || st().is_some_and(|s| s.buffer.memory == 0 && s.buffer.spilled == 0),
    );

    check_rows(&rt, &db, &points, &seen);
    let last = st().unwrap();
    assert_eq!(last.recovery.lost, 0, "{last:?}");
    assert_eq!(last.buffer.dropped, 0, "{last:?}");
    assert_eq!(last.received.rejected, 0, "{last:?}");
    check_events_and_aggregates(&rt, &db, &points, &seen);
    check_tree(&rt, &db);
    check_grafana_queries(&rt, &db);
    check_history_cli(d, &router_ep, &rt, &db);
    check_alarms_cli(&pg);
    check_retention(&rt, &db);

    let log = std::fs::read_to_string(d.join("historian.log")).unwrap();
    assert!(
        !log.contains(&pg.password),
        "the password appears in the historian's log"
    );
    let mut hist = hist;
    unsafe { libc::kill(hist.0.id() as i32, libc::SIGTERM) };
    let t = Instant::now();
    let code = loop {
        if let Some(c) = hist.0.try_wait().unwrap() {
            break c;
        }
        assert!(
            t.elapsed() < Duration::from_secs(30),
            "historian did not stop on SIGTERM"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(
        code.success(),
        "historian exit {code}: {}",
        log.lines().rev().take(20).collect::<Vec<_>>().join("\n")
    );
    drop(router);
}

/// The seqs the router carried for `point` that the database does not hold.
fn seen_not_stored(
    rt: &tokio::runtime::Runtime,
    db: &tokio_postgres::Client,
    point: &str,
    seen: &BTreeMap<u64, bool>,
) -> Vec<u64> {
    let stored: BTreeSet<u64> = rt
        .block_on(db.query(
            "SELECT w.seq FROM windows w JOIN points p USING (point_id) WHERE p.key = $1",
            &[&point],
        ))
        .unwrap()
        .iter()
        .map(|r| r.get::<_, i64>(0) as u64)
        .collect();
    seen.keys()
        .filter(|s| !stored.contains(s))
        .copied()
        .collect()
}

/// One row per window per point: each run's seqs 1..=max, none twice, none missing, and
/// every window the router carried is there.
fn check_rows(
    rt: &tokio::runtime::Runtime,
    db: &tokio_postgres::Client,
    points: &[&str],
    seen: &BTreeMap<String, BTreeMap<u64, bool>>,
) {
    for p in points {
        let rows = rt
            .block_on(db.query(
                "SELECT w.run_start, array_agg(w.seq ORDER BY w.seq), count(*), count(DISTINCT w.seq)
                 FROM windows w JOIN points p USING (point_id) WHERE p.key = $1 GROUP BY 1",
                &[p],
            ))
            .unwrap();
        assert_eq!(rows.len(), 1, "{p}: one daemon run expected");
        let seqs: Vec<i64> = rows[0].get(1);
        let (n, distinct): (i64, i64) = (rows[0].get(2), rows[0].get(3));
        assert_eq!(n, distinct, "{p}: a window stored twice");
        let max = *seqs.last().unwrap();
        assert_eq!(
            seqs,
            (1..=max).collect::<Vec<i64>>(),
            "{p}: windows missing in the database"
        );
        let stored: BTreeSet<u64> = seqs.iter().map(|&s| s as u64).collect();
        let missing: Vec<u64> = seen[*p]
            .keys()
            .filter(|s| !stored.contains(s))
            .copied()
            .collect();
        assert!(
            missing.is_empty(),
            "{p}: seen on the router, not stored: {missing:?}"
        );
    }
}

/// One event per state change, with the state it left; aggregates add up to the windows.
fn check_events_and_aggregates(
    rt: &tokio::runtime::Runtime,
    db: &tokio_postgres::Client,
    points: &[&str],
    seen: &BTreeMap<String, BTreeMap<u64, bool>>,
) {
    let q = |sql: &str, p: &str| -> i64 { rt.block_on(db.query_one(sql, &[&p])).unwrap().get(0) };
    let mut total_events = 0;
    for p in points {
        let changes = q("SELECT count(*) FROM windows w JOIN points p USING (point_id) WHERE p.key = $1 AND w.state_changed", p);
        let events = q(
            "SELECT count(*) FROM events e JOIN points p USING (point_id) WHERE p.key = $1",
            p,
        );
        let seen_changes = seen[*p].values().filter(|c| **c).count() as i64;
        assert_eq!(events, changes, "{p}: one event per state change");
        assert!(
            events >= seen_changes && events >= 1,
            "{p}: {events} events, {seen_changes} changes seen on the router"
        );
        let wrong = q(
            "SELECT count(*) FROM events e JOIN points p USING (point_id)
             JOIN windows w ON w.point_id = e.point_id AND w.time = e.time
             WHERE p.key = $1 AND (e.to_state <> w.state OR e.from_state IS DISTINCT FROM
               (SELECT v.state FROM windows v WHERE v.point_id = e.point_id AND v.time < e.time ORDER BY v.time DESC LIMIT 1)
               OR e.message->>'state' <> e.to_state)",
            p,
        );
        assert_eq!(wrong, 0, "{p}: events disagree with the windows");
        let windows = q(
            "SELECT count(*) FROM windows w JOIN points p USING (point_id) WHERE p.key = $1",
            p,
        );
        let in_minutes = q("SELECT coalesce(sum(m.windows), 0)::int8 FROM minutes m JOIN points p USING (point_id) WHERE p.key = $1", p);
        assert_eq!(
            in_minutes, windows,
            "{p}: 1-minute aggregates must count every window once"
        );
        let latest = q(
            "SELECT l.seq FROM point_latest l JOIN points p USING (point_id) WHERE p.key = $1",
            p,
        );
        assert_eq!(latest, windows, "{p}: the latest window is the last seq");
        let status = q(
            "SELECT count(*) FROM point_status s JOIN points p USING (point_id) WHERE p.key = $1",
            p,
        );
        assert_eq!(status, 1, "{p}: the daemon's status is stored");
        total_events += events;
    }
    assert!(total_events >= 3);
}

fn check_tree(rt: &tokio::runtime::Runtime, db: &tokio_postgres::Client) {
    let tree: Vec<(String, String)> = rt
        .block_on(db.query("SELECT site, key FROM asset_tree ORDER BY key", &[]))
        .unwrap()
        .iter()
        .map(|r| (r.get(0), r.get(1)))
        .collect();
    assert_eq!(
        tree,
        [
            ("plant".to_string(), "cwru-de/motor/de".to_string()),
            ("plant".into(), "cwru-fe/motor/fe".into()),
            ("lut-lab".into(), "lut-rig/shaft/nde".into())
        ],
        "site from the rig file, else the historian's default_site"
    );
}

/// The dashboard's queries with Grafana's macros filled in, run against the database.
fn check_grafana_queries(rt: &tokio::runtime::Runtime, db: &tokio_postgres::Client) {
    let g = repo().join("config/grafana");
    for y in [
        "provisioning/datasources/rigmon.yaml",
        "provisioning/dashboards/rigmon.yaml",
    ] {
        let v: serde_yaml::Value =
            serde_yaml::from_str(&std::fs::read_to_string(g.join(y)).unwrap()).unwrap();
        assert_eq!(v["apiVersion"], serde_yaml::Value::from(1), "{y}");
    }
    let dash: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(g.join("dashboards/fleet.json")).unwrap())
            .unwrap();
    let var_sql = dash["templating"]["list"][0]["query"].as_str().unwrap();
    let vars = rt.block_on(db.query(var_sql, &[])).unwrap();
    assert_eq!(vars.len(), 3, "the point variable lists the three points");
    let lut: i32 = vars
        .iter()
        .find(|r| r.get::<_, String>(0) == "lut-rig/shaft/nde")
        .unwrap()
        .get(1);
    let fill = |sql: &str| {
        let mut s = sql.replace("$point", &lut.to_string());
        while let Some(i) = s.find("$__timeFilter(") {
            let end = i + s[i..].find(')').unwrap();
            let col = &s[i + "$__timeFilter(".len()..end];
            let cond =
                format!("{col} BETWEEN now() - interval '2 hours' AND now() + interval '1 hour'");
            s.replace_range(i..=end, &cond);
        }
        s
    };
    let panels = dash["panels"].as_array().unwrap();
    assert!(panels.len() >= 5);
    for p in panels {
        for t in p["targets"].as_array().unwrap() {
            let sql = fill(t["rawSql"].as_str().unwrap());
            let rows = rt
                .block_on(db.query(sql.as_str(), &[]))
                .unwrap_or_else(|e| panic!("panel {:?}: {e}\n{sql}", p["title"]));
            assert!(
                !rows.is_empty(),
                "panel {:?} shows nothing:\n{sql}",
                p["title"]
            );
            if p["title"] == "State now per point" {
                assert_eq!(rows.len(), 3);
            }
        }
    }
    let ds = std::fs::read_to_string(g.join("provisioning/datasources/rigmon.yaml")).unwrap();
    assert!(
        ds.contains("$__file{"),
        "the data source password comes from a file"
    );
}

fn check_history_cli(
    d: &Path,
    router: &str,
    rt: &tokio::runtime::Runtime,
    db: &tokio_postgres::Client,
) {
    let stored: i64 = rt
        .block_on(db.query_one("SELECT count(*) FROM windows w JOIN points p USING (point_id) WHERE p.key = 'lut-rig/shaft/nde'", &[]))
        .unwrap()
        .get(0);
    let z = ["--connect", router];
    let out = rigmon(
        &[
            &[
                "history",
                "rigmon/lut-rig/shaft/nde",
                "--since",
                "2h",
                "--json",
            ][..],
            &z,
        ]
        .concat(),
        &[],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(
        lines.len() as i64,
        stored,
        "one history reply per stored window"
    );
    let seqs: Vec<u64> = lines.iter().map(|v| v["seq"].as_u64().unwrap()).collect();
    assert_eq!(
        seqs,
        (1..=stored as u64).collect::<Vec<_>>(),
        "in time order"
    );
    assert!(lines
        .iter()
        .all(|v| v["schema"] == "rigmon.health" && v["site"] == "lut-lab"));
    // The daemon's health indicators, stored and read back (issue 35 item 3): every window
    // of the replayed recording has them, and history gives the stored values.
    let stored_rms: Vec<Option<f32>> = rt
        .block_on(db.query(
            "SELECT w.indicator_rms FROM windows w JOIN points p USING (point_id)
             WHERE p.key = 'lut-rig/shaft/nde' ORDER BY w.seq",
            &[],
        ))
        .unwrap()
        .iter()
        .map(|r| r.get(0))
        .collect();
    assert!(
        stored_rms.iter().all(|v| v.is_some_and(|v| v > 0.0)),
        "every window's indicators stored: {stored_rms:?}"
    );
    let back_rms: Vec<Option<f32>> = lines
        .iter()
        .map(|v| {
            let rms = v["indicators"]["values"]["rms"].as_f64()? as f32;
            let kurtosis = v["indicators"]["values"]["kurtosis"].as_f64()?;
            kurtosis.is_finite().then_some(rms)
        })
        .collect();
    assert_eq!(back_rms, stored_rms, "history gives the stored indicators");
    let (n, windows): (i64, i64) = {
        let r = rt
            .block_on(db.query_one(
                "SELECT sum(m.indicators_n)::int8, sum(m.windows)::int8 FROM minutes m
                 JOIN points p USING (point_id) WHERE p.key = 'lut-rig/shaft/nde'",
                &[],
            ))
            .unwrap();
        (r.get(0), r.get(1))
    };
    assert_eq!(
        (n, windows),
        (stored, stored),
        "the minutes count every window's indicators once"
    );
    let png = d.join("trend.png");
    let out = rigmon(
        &[
            &[
                "history",
                "rigmon/lut-rig/**",
                "--since",
                "2h",
                "--png",
                png.to_str().unwrap(),
            ][..],
            &z,
        ]
        .concat(),
        &[],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(text.lines().count() as i64, stored);
    assert!(
        text.lines().all(|l| l.contains("lut-rig/shaft/nde")),
        "{text}"
    );
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    let (w, h) = (
        u32::from_be_bytes(bytes[16..20].try_into().unwrap()),
        u32::from_be_bytes(bytes[20..24].try_into().unwrap()),
    );
    assert_eq!((w, h), (1400, 900));
    assert!(
        bytes.len() > 20_000,
        "a trend with three panels, not an empty picture ({} bytes)",
        bytes.len()
    );
    let out = rigmon(
        &[
            &[
                "history",
                "rigmon/**",
                "--since",
                "2h",
                "--png",
                png.to_str().unwrap(),
            ][..],
            &z,
        ]
        .concat(),
        &[],
    );
    assert!(
        !out.status.success()
            && String::from_utf8_lossy(&out.stderr).contains("--png draws one point")
    );
    let out = rigmon(
        &[
            &[
                "history",
                "rigmon/nowhere/x/y",
                "--since",
                "2h",
                "--timeout",
                "3",
            ][..],
            &z,
        ]
        .concat(),
        &[],
    );
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("no history"));
}

fn check_alarms_cli(pg: &Postgres) {
    let env = pg.env("fleet");
    let out = rigmon(&["alarms", "--json"], &env);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let all: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(all.len() >= 3);
    let id = all[0]["id"].as_i64().unwrap().to_string();
    let out = rigmon(
        &[
            "ack",
            &id,
            "--user",
            "alice",
            "--comment",
            "bearing inspected",
        ],
        &env,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("acked by alice"));
    let out = rigmon(&["alarms", "--unacked", "--json"], &env);
    assert_eq!(
        String::from_utf8_lossy(&out.stdout).lines().count(),
        all.len() - 1
    );
    let out = rigmon(&["ack", &id, "--user", "bob"], &env);
    assert!(
        !out.status.success()
            && String::from_utf8_lossy(&out.stderr).contains("already acknowledged by alice")
    );
    let out = rigmon(&["alarms"], &env);
    assert!(String::from_utf8_lossy(&out.stdout).contains("bearing inspected"));
}

fn check_retention(rt: &tokio::runtime::Runtime, db: &tokio_postgres::Client) {
    rt.block_on(db.batch_execute("CREATE TABLE windows_p20000101 PARTITION OF windows FOR VALUES FROM ('2000-01-01 00:00:00+00') TO ('2000-01-02 00:00:00+00')")).unwrap();
    let dropped = rt
        .block_on(rigmon::historian::partitions::apply_retention(
            db,
            30,
            3650,
            std::time::SystemTime::now(),
        ))
        .unwrap();
    assert_eq!(
        dropped,
        ["windows_p20000101"],
        "only the partition past its retention goes"
    );
}

#[test]
fn bad_database_settings_are_refused_at_start() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("h.toml");
    std::fs::write(
        &cfg,
        "[database]\nurl = \"postgresql://rigmon:hunter2@127.0.0.1/rigmon\"\n",
    )
    .unwrap();
    let out = rigmon(&["historian", "--config", cfg.to_str().unwrap()], &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("carries a password") && !err.contains("hunter2"),
        "{err}"
    );
    std::fs::write(&cfg, "[database]\n").unwrap();
    let env = [
        ("PGSSLMODE".to_string(), "verify-full".to_string()),
        ("PGUSER".into(), "x".into()),
    ];
    let out = rigmon(&["historian", "--config", cfg.to_str().unwrap()], &env);
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("without TLS"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let pass = d.path().join("pgpass");
    std::fs::write(&pass, "*:*:*:*:pw\n").unwrap();
    std::fs::set_permissions(&pass, std::fs::Permissions::from_mode(0o644)).unwrap();
    let env = [
        ("PGPASSFILE".to_string(), pass.display().to_string()),
        ("PGHOST".into(), "127.0.0.1".into()),
        ("PGUSER".into(), "x".into()),
    ];
    let out = rigmon(&["alarms"], &env);
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("chmod 600"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn the_historian_unit_verifies() {
    let unit = std::fs::read_to_string(repo().join("systemd/rigmon-historian.service")).unwrap();
    for key in [
        "Type=notify",
        "WatchdogSec=",
        "DynamicUser=yes",
        "ProtectSystem=strict",
        "NoNewPrivileges=yes",
        "LoadCredential=pgpass:",
        "PGPASSFILE=%d/pgpass",
    ] {
        assert!(unit.contains(key), "{key} missing");
    }
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("rigmon-historian.service");
    std::fs::write(&p, unit.replace("/usr/local/bin/rigmon", bin())).unwrap();
    let out = Command::new("systemd-analyze")
        .args(["verify", "--man=no"])
        .arg(&p)
        .output()
        .expect("systemd-analyze (apt-get install systemd)");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success() && !text.contains("rigmon-historian.service:"),
        "{text}"
    );
}

/// A version-1 database as the first historian left it: the schema migration 1 recorded and
/// one window of `lut-rig/shaft/nde` at `time` (columns as version 1 had them).
fn version_1_database(
    rt: &tokio::runtime::Runtime,
    db: &tokio_postgres::Client,
    time: std::time::SystemTime,
) {
    let (version, name, sql) = rigmon::historian::migrations::MIGRATIONS[0];
    assert_eq!(version, 1);
    rt.block_on(async {
        db.batch_execute(
            "CREATE TABLE rigmon_schema_migrations (version integer PRIMARY KEY,
                 name text NOT NULL, applied_at timestamptz NOT NULL DEFAULT now())",
        )
        .await
        .unwrap();
        db.batch_execute(sql).await.unwrap();
        db.execute(
            "INSERT INTO rigmon_schema_migrations (version, name) VALUES ($1, $2)",
            &[&version, &name],
        )
        .await
        .unwrap();
        rigmon::historian::partitions::Partitions::default()
            .ensure(db, [time].into_iter())
            .await
            .unwrap();
        db.batch_execute(
            "WITH s AS (INSERT INTO sites (name) VALUES ('lut-lab') RETURNING site_id),
                  m AS (INSERT INTO machines (site_id, name) SELECT site_id, 'lut-rig' FROM s
                        RETURNING machine_id),
                  a AS (INSERT INTO assets (machine_id, name) SELECT machine_id, 'shaft' FROM m
                        RETURNING asset_id)
             INSERT INTO points (asset_id, name, key, band_channel, band_orders, software_version)
             SELECT asset_id, 'nde', 'lut-rig/shaft/nde', 'vertical', '{\"bpfo\": 3.58}', '0.1.0'
             FROM a;
             INSERT INTO models (name, sha256, labels) VALUES ('lut-rig', 'ab', '{healthy,outer_race}');",
        )
        .await
        .unwrap();
        db.execute(
            "INSERT INTO windows (point_id, time, window_s, run_start, seq, publish_time, state,
                 state_since, state_changed, confidence, window_state, model_id, p_healthy,
                 p_outer_race, novelty, novelty_threshold, rpm, speed_source, quality_ok,
                 clipped_samples, nan_samples, dropout_samples, missing_tacho_pulses)
             SELECT point_id, $1::timestamptz, 1.0, $1::timestamptz - interval '10 s', 10, $1,
                 'healthy', $1::timestamptz - interval '9 s', false, 0.875, 'healthy', model_id,
                 0.875, 0.125, 0.25, 1.0,
                 588.0, 'tacho', true, 0, 0, 0, 0
             FROM points, models",
            &[&time],
        )
        .await
        .unwrap();
    });
}

/// A window of `lut-rig/shaft/nde` from a run that started at `run_ns`, every field set: a
/// class decided by the fault-family evidence overruling the classifier, the evidence, a
/// speed read from the vibration with its confidence and rival, a foreign model allowed on
/// purpose. Not stored, so left empty: `quality.dsp` and `quality.flat_channels`. The
/// numbers are exact in `real` where the column is `real`.
pub(crate) fn every_field_set(run_ns: u64, seq: u64) -> rigmon::wire::health::HealthMessage {
    use rigmon::wire::health::*;
    let labels: Vec<String> = rigmon::model::ALL_LABELS
        .iter()
        .map(|s| s.to_string())
        .collect();
    let end_s = 2.0 + seq as f64;
    HealthMessage {
        schema: SCHEMA.into(),
        schema_version: SCHEMA_VERSION,
        rig: "lut-rig".into(),
        asset: "shaft".into(),
        point: "nde".into(),
        site: Some("lut-lab".into()),
        seq,
        window: WindowTimes {
            start_s: end_s - 1.0,
            end_s,
            start_ns: run_ns + (end_s as u64 - 1) * 1_000_000_000,
            end_ns: run_ns + end_s as u64 * 1_000_000_000,
        },
        publish_time_ns: run_ns + end_s as u64 * 1_000_000_000 + 12_345_000,
        rpm: Some(1_471.5),
        speed_source: rigmon::vocabulary::SpeedSourceKind::Estimate,
        speed_confidence: Some(0.8125),
        speed_rival_rpm: Some(735.75),
        quality: QualityReport {
            ok: false,
            flags: vec!["dc_offset".into()],
            clipped_samples: 1,
            nan_samples: 2,
            dropout_samples: 3,
            flat_channels: Vec::new(),
            missing_tacho_pulses: 4,
            dsp: serde_json::Value::Null,
        },
        probabilities: labels
            .iter()
            .cloned()
            .zip([0.625, 0.0625, 0.25, 0.0625])
            .collect(),
        window_state: "inner_race".into(),
        unknown_reason: None,
        alarm_despite: Some(rigmon::health::UnknownReason::Novelty),
        decision: rigmon::health::Basis::Impulsive,
        overruled: Some("healthy".into()),
        evidence: Some(rigmon::model::evidence::FamilyEvidence {
            outer_race: 0.5,
            inner_race: 7.25,
            ball: -1.125,
        }),
        impulse: Some(rigmon::model::impulsiveness::Impulse {
            beyond_healthy: 12.5,
            beyond_gaussian: 7.25,
        }),
        indicators: Some(every_indicator_set()),
        state: "inner_race".into(),
        state_since_s: 2.5,
        state_changed: seq == 1,
        confidence: 0.75,
        novelty: 1.5,
        novelty_threshold: 1.25,
        baseline_distance: Some(6.5),
        beyond_baseline: Some(true),
        fault_bands: FaultBands {
            channel: "vertical".into(),
            orders: [("bpfo".to_string(), 3.58), ("bpfi".to_string(), 5.42)].into(),
            bpfo: vec![0.5, 0.25, 0.125],
            bpfi: vec![2.0, 1.0, 0.5],
            two_bsf: vec![0.0625, 0.03125, 0.015625],
            floor: 0.0078125,
        },
        velocity_rms_mm_s: Some(2.875),
        iso_zone: Some(rigmon::health::iso20816::Zone::B),
        model: ModelInfo {
            id: "lut-rig".into(),
            sha256: "ab".into(),
            labels,
            foreign: vec![
                "rig_id: model cwru-de, rig file lut-rig".into(),
                "axis: model radial, rig file axial".into(),
            ],
        },
        calibration_id: Some("cal-2026-11-26".into()),
        software_version: "0.1.0".into(),
    }
}

/// Health indicators and a departure reading with every field set (exact in `real`); the
/// machine departed 2 s into the run.
fn every_indicator_set() -> rigmon::wire::health::HealthIndicators {
    use rigmon::model::indicators::{Indicator, Indicators, PerIndicator};
    rigmon::wire::health::HealthIndicators {
        values: Indicators {
            rms: 0.25,
            crest: 4.5,
            kurtosis: 1.75,
            resonance: 0.125,
            samples: 2560,
        },
        departure: Some(rigmon::model::departure::DepartureReading {
            scores: PerIndicator::from_array([1.5, -0.5, 6.25, 3.0]),
            smoothed: Some(PerIndicator::from_array([1.25, -0.25, 5.5, 2.75])),
            threshold: PerIndicator::from_array([4.0, 4.5, 5.0, 4.25]),
            leading: Some(Indicator::Kurtosis),
            excess: Some(0.5),
            beyond_for: 31,
            departed_since_s: Some(2.0),
        }),
    }
}

#[test]
fn every_health_field_survives_the_historian_and_a_version_1_database_is_upgraded() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let pg = Postgres::with_fleet_database();
    let now_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis() as u64;
    let old_time = std::time::UNIX_EPOCH + Duration::from_millis(now_ms - 30 * 60_000);
    let (rt, db) = pg.client("fleet");
    version_1_database(&rt, &db, old_time);

    let (router_ep, router) = loopback_router();
    let _hist = historian(d, &pg, &router_ep);
    let versions = || -> Vec<i32> {
        rt.block_on(db.query(
            "SELECT version FROM rigmon_schema_migrations ORDER BY 1",
            &[],
        ))
        .unwrap()
        .iter()
        .map(|r| r.get(0))
        .collect()
    };
    wait_until(
        "the historian to migrate the version-1 database",
        Duration::from_secs(60),
        || versions() == [1, 2, 3, 4],
    );

    // A daemon's two windows: the first with every field set, the second with the optional
    // ones absent (they must come back absent, not as zeros).
    let run_ns = (now_ms - 60_000) * 1_000_000;
    let full = every_field_set(run_ns, 1);
    let mut bare = every_field_set(run_ns, 2);
    bare.decision = rigmon::health::Basis::Model;
    bare.overruled = None;
    bare.evidence = None;
    bare.impulse = None;
    bare.indicators = None;
    bare.speed_confidence = None;
    bare.speed_rival_rpm = None;
    bare.model.foreign.clear();
    let client = loopback_client(&router_ep);
    let rows = || -> i64 {
        rt.block_on(db.query_one("SELECT count(*) FROM windows", &[]))
            .unwrap()
            .get(0)
    };
    wait_until(
        "both windows in the database",
        Duration::from_secs(60),
        || {
            // published until stored (the historian may still be subscribing; it skips repeats)
            for m in [&full, &bare] {
                client
                    .put(
                        "rigmon/lut-rig/shaft/nde/health",
                        serde_json::to_vec(m).unwrap(),
                    )
                    .wait()
                    .unwrap();
            }
            std::thread::sleep(Duration::from_millis(500));
            rows() == 3
        },
    );

    let stored = rt
        .block_on(db.query_one(
            "SELECT decision, overruled, evidence_outer_race, evidence_inner_race, evidence_ball,
                    speed_confidence, speed_rival_rpm, model_foreign, impulse_beyond_healthy,
                    impulse_beyond_gaussian
             FROM windows WHERE seq = 1",
            &[],
        ))
        .unwrap();
    assert_eq!(stored.get::<_, String>(0), "impulsive");
    assert_eq!(
        stored.get::<_, Option<String>>(1).as_deref(),
        Some("healthy")
    );
    assert_eq!(
        (1..=3)
            .map(|i| stored.get::<_, f32>(i + 1))
            .collect::<Vec<_>>(),
        [0.5, 7.25, -1.125]
    );
    assert_eq!(stored.get::<_, f32>(5), 0.8125);
    assert_eq!(stored.get::<_, f64>(6), 735.75);
    assert_eq!(stored.get::<_, Vec<String>>(7), full.model.foreign);
    assert_eq!(
        (stored.get::<_, f32>(8), stored.get::<_, f32>(9)),
        (12.5, 7.25)
    );
    // schema 4: the indicators and the departure reading in typed columns, and in the
    // 1-minute aggregates (the bare window has none)
    let ind = rt
        .block_on(db.query_one(
            "SELECT indicator_rms, indicator_kurtosis, indicator_samples, departure_score_kurtosis,
                    departure_smoothed_kurtosis, departure_threshold_kurtosis, departure_leading,
                    departure_excess, departure_beyond_for,
                    extract(epoch FROM departed_since - run_start)::float8
             FROM windows WHERE seq = 1",
            &[],
        ))
        .unwrap();
    assert_eq!(
        (
            ind.get::<_, f32>(0),
            ind.get::<_, f32>(1),
            ind.get::<_, i32>(2)
        ),
        (0.25, 1.75, 2560)
    );
    assert_eq!(
        (3..=5).map(|i| ind.get::<_, f32>(i)).collect::<Vec<_>>(),
        [6.25, 5.5, 5.0]
    );
    assert_eq!(ind.get::<_, String>(6), "kurtosis");
    assert_eq!(
        (
            ind.get::<_, f32>(7),
            ind.get::<_, i32>(8),
            ind.get::<_, f64>(9)
        ),
        (0.5, 31, 2.0)
    );
    let agg = rt
        .block_on(db.query_one(
            "SELECT sum(indicators_n)::int8, max(indicator_rms_max), sum(indicator_kurtosis_sum),
                    sum(departed_windows)::int8, sum(windows)::int8
             FROM minutes WHERE minute > now() - interval '10 minutes'",
            &[],
        ))
        .unwrap();
    assert_eq!(
        (
            agg.get::<_, i64>(0),
            agg.get::<_, f32>(1),
            agg.get::<_, f64>(2),
            agg.get::<_, i64>(3),
            agg.get::<_, i64>(4)
        ),
        (1, 0.25, 1.75, 1, 2),
        "two windows this run, one with indicators and departed"
    );
    let refused = rt.block_on(db.execute("UPDATE windows SET decision = 'guess'", &[]));
    assert!(
        refused.is_err_and(|e| format!("{e:?}").contains("windows_decision_check")),
        "decision is one of model, confirmed, evidence, impulsive"
    );

    // Back over Zenoh, as `rigmon history` asks: field for field what the daemon sent.
    let out = rigmon(
        &[
            "history",
            "rigmon/lut-rig/shaft/nde",
            "--since",
            "2h",
            "--json",
            "--connect",
            &router_ep,
        ],
        &[],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let back: Vec<rigmon::wire::health::HealthMessage> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(back.len(), 3, "the version-1 window and the two new ones");
    assert_eq!(back[1], full);
    assert_eq!(back[2], bare);
    assert_eq!(
        (
            back[1].decision,
            back[1].overruled.as_deref(),
            back[1].evidence.map(|e| e.inner_race),
            back[1].speed_confidence,
            back[1].speed_rival_rpm,
            back[1].model.foreign.len()
        ),
        (
            rigmon::health::Basis::Impulsive,
            Some("healthy"),
            Some(7.25),
            Some(0.8125),
            Some(735.75),
            2
        )
    );
    // The version-1 window reads as its message did: decided by the model, the rest absent.
    let old = &back[0];
    assert_eq!(
        (old.seq, old.state.as_str(), old.rpm, old.confidence),
        (10, "healthy", Some(588.0), 0.875)
    );
    assert_eq!(old.decision, rigmon::health::Basis::Model);
    assert!(
        old.overruled.is_none()
            && old.evidence.is_none()
            && old.indicators.is_none()
            && old.impulse.is_none()
            && old.speed_confidence.is_none()
            && old.speed_rival_rpm.is_none()
            && old.model.foreign.is_empty()
    );
    drop(router);
}

/// Issue 38, F1, F2, F3, F11, F12: the historian trusted every field of every health
/// message. One window dated 2400 became the point's state now (`fleet_now` said `healthy`
/// while the daemon said otherwise) and made a partition for its day; seq 2^64-1 wrapped
/// the gap tracker into a recovery storm; a machine named `c3*bad` broke `rigmon history`
/// for every point ("point key ...: Invalid K... at <source path>"); any publisher could
/// write for any machine. Now each is refused and counted by reason in the status, the
/// rows of the honest windows are all there and nothing else is, and history, fleet_now
/// and `rigmon alarms --point` (its `_` no LIKE wildcard) answer as they should.
#[test]
fn hostile_health_messages_are_refused_counted_and_break_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let pg = Postgres::with_fleet_database();
    let (router_ep, router) = loopback_router();
    let client = loopback_client(&router_ep);
    let (_status_sub, status) = historian_status(&client);
    let st = || status.lock().unwrap().clone();
    let _hist = historian(d, &pg, &router_ep);
    wait_until(
        "the historian's status with its database connected",
        Duration::from_secs(60),
        || st().is_some_and(|s| s.database.connected),
    );
    std::thread::sleep(Duration::from_secs(1));

    let now_ns = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64;
    let run_ns = now_ns - 60_000_000_000;
    // A window of `rig` numbered `seq`, ending `end_s` into the run at `end_ns`.
    let window = |rig: &str, seq: u64, end_ns: u64, end_s: f64| -> Vec<u8> {
        let mut m = every_field_set(run_ns, seq.min(1_000));
        m.rig = rig.into();
        m.seq = seq;
        m.window.end_s = end_s;
        m.window.start_s = end_s - 1.0;
        m.window.end_ns = end_ns;
        m.window.start_ns = end_ns - 1_000_000_000;
        m.publish_time_ns = now_ns;
        serde_json::to_vec(&m).unwrap()
    };
    let at = |seq: u64| run_ns + (2 + seq) * 1_000_000_000;
    let end_s = |seq: u64| 2.0 + seq as f64;
    let put = |key: &str, payload: Vec<u8>| {
        client.put(key, payload).wait().unwrap();
        std::thread::sleep(Duration::from_millis(30));
    };
    let ok_key = "rigmon/h-ok/shaft/nde/health";
    for seq in 1..=3 {
        put(ok_key, window("h-ok", seq, at(seq), end_s(seq)));
    }
    put(ok_key, window("h*bad", 1, at(1), end_s(1))); // F3: refused (name)
    put(
        "rigmon/h-spoof/shaft/nde/health",
        window("h-ok", 4, at(4), end_s(4)),
    ); // F11 (key)
    let mut y2400 = every_field_set(run_ns, 4);
    y2400.rig = "h-ok".into();
    y2400.state = "healthy".into();
    y2400.window.end_ns = (430.0 * 365.25 * 86400e9) as u64;
    y2400.window.start_ns = y2400.window.end_ns - 1_000_000_000;
    put(ok_key, serde_json::to_vec(&y2400).unwrap()); // F1, F12 (future)
    put(ok_key, vec![b' '; 2 << 20]); // F8: 2 MB, refused before it is buffered
    for seq in 5..=6 {
        put(ok_key, window("h-ok", seq, at(seq), end_s(seq)));
    }
    let seq_key = "rigmon/h-seq/shaft/nde/health";
    for seq in [1, 2, 3, u64::MAX, 4, 5, 6, 7, 8] {
        let k = if seq == u64::MAX { 3 } else { seq };
        put(
            seq_key,
            window("h-seq", seq, at(k) + 500_000_000, end_s(k) + 0.5),
        ); // F2 (seq)
    }
    put(
        "rigmon/h-two/shaft/nde/health",
        window("h-two", 1, at(1), end_s(1)),
    );

    let (rt, db) = pg.client("fleet");
    let count = |sql: &str| -> i64 { rt.block_on(db.query_one(sql, &[])).unwrap().get(0) };
    wait_until(
        "the 14 honest windows in the database",
        Duration::from_secs(30),
        || count("SELECT count(*) FROM windows") >= 14,
    );
    wait_until(
        "the refusals counted in the status",
        Duration::from_secs(20),
        || st().is_some_and(|s| s.received.refused.total() >= 5 && s.recovery.lost >= 1),
    );
    let s = st().unwrap();
    let r = s.received.refused;
    assert_eq!(
        (r.key, r.name, r.future, r.seq, r.too_large),
        (1, 1, 1, 1, 1),
        "{s:?}"
    );
    assert_eq!(count("SELECT count(*) FROM windows"), 14);
    assert_eq!(
        count("SELECT count(*) FROM windows w JOIN points p USING (point_id) WHERE p.key = 'h-seq/shaft/nde'"),
        8
    );
    assert_eq!(
        count("SELECT count(*) FROM points WHERE key NOT IN ('h-ok/shaft/nde', 'h-seq/shaft/nde', 'h-two/shaft/nde')"),
        0,
        "no point for the refused names"
    );
    // F2: the one real gap (h-ok's seq 4) asked for once, no storm, no wrapped counter.
    let rec = s.recovery;
    assert!(
        rec.gaps == 1 && rec.requested == 1 && rec.lost == 1,
        "{rec:?}"
    );
    // F1: the state now is the newest honest window's; F12: no partition beyond today.
    let now_row = rt
        .block_on(db.query_one(
            "SELECT state, time < now() + interval '1 day' FROM fleet_now WHERE machine = 'h-ok'",
            &[],
        ))
        .unwrap();
    assert_eq!(
        (now_row.get::<_, String>(0), now_row.get::<_, bool>(1)),
        ("inner_race".to_string(), true)
    );
    assert_eq!(
        count(
            "SELECT count(*) FROM pg_inherits i JOIN pg_class c ON c.oid = i.inhrelid
             JOIN pg_class p ON p.oid = i.inhparent
             WHERE p.relname = 'windows' AND c.relname > 'windows_p2100'"
        ),
        0
    );

    // F3: a bad key already in the database (an older historian stored it) breaks nothing.
    rt.block_on(db.execute(
        "UPDATE points SET key = 'h*two/shaft/nde' WHERE key = 'h-two/shaft/nde'",
        &[],
    ))
    .unwrap();
    for (key, n) in [("rigmon/h-ok/shaft/nde", 5), ("rigmon/**", 13)] {
        let out = rigmon(
            &[
                "history",
                key,
                "--since",
                "2h",
                "--json",
                "--timeout",
                "10",
                "--connect",
                &router_ep,
            ],
            &[],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "history {key}: {err}");
        assert_eq!(
            String::from_utf8_lossy(&out.stdout).lines().count(),
            n,
            "{key}"
        );
        assert!(!err.contains(".rs:"), "{err}");
    }
    // SQL: `_` in a point pattern is itself, not LIKE's any character.
    let alarms = |pattern: &str| -> usize {
        let out = rigmon(&["alarms", "--json", "--point", pattern], &pg.env("fleet"));
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).lines().count()
    };
    assert_eq!(alarms("h-ok/*"), 1);
    assert_eq!(alarms("h_ok/*"), 0);
    drop(router);
}
