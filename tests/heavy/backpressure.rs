//! Issue 40: a historian slower than its fleet loses nothing in silence. Real parts: a
//! PostgreSQL started here, a Zenoh router in this process (loopback, explicit endpoints,
//! multicast scouting off), the built `rigmon historian`, and points that publish with the
//! fleet's congestion policy and keep the daemon's own recent history
//! (`rigmon::publish::recent::RecentHistory`). The database is stalled (a lock on `windows`
//! held by another session) while the points publish faster than the historian can keep:
//! its memory buffer and spill fill and it drops. Afterwards every published window must be
//! in the database or in the historian's loss ledger by point and seq range (its last
//! status and its log), and the ledger must name no window that is in the database.

use super::historian::{
    bin, every_field_set, historian_status, loopback_client, loopback_router, wait_until, Guard,
    Postgres,
};
use rigmon::historian::status::HistorianStatus;
use rigmon::publish::recent::RecentHistory;
use rigmon::publish::zenoh::FLEET_CONGESTION;
use std::collections::BTreeSet;
use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::Duration;
use zenoh::Wait;

const POINTS: usize = 10;
/// Windows per point counted by the test ...
const TICKS: u64 = 40;
/// ... then a few more, as a running daemon publishes its next windows.
const TAIL: u64 = 5;
/// Windows each point's recent history keeps (a daemon's `[zenoh] history_windows`).
const KEPT: usize = 15;

pub(crate) fn now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64
}

/// The historian with a small buffer (50 messages in memory, ~64 KB of spill), so that a
/// stalled database makes it drop; its last status comes on stdout (`--summary-json`).
fn slow_historian(dir: &Path, pg: &Postgres, router: &str) -> Guard {
    test_historian(
        dir,
        pg,
        router,
        "[buffer]\nmemory_messages = 50\nspill_dir = \"spill\"\nspill_max_mb = 0.0625\n\
         [batch]\nmax_delay_ms = 100\n[recovery]\nquery_timeout_s = 5.0\n",
    )
}

/// The historian `test` on the fleet database and the router, with `sections` of
/// `historian.toml` after its name and Zenoh client settings; its log in `dir`, its last
/// status on stdout (`--summary-json`).
pub(crate) fn test_historian(dir: &Path, pg: &Postgres, router: &str, sections: &str) -> Guard {
    let cfg = dir.join("historian.toml");
    std::fs::write(
        &cfg,
        format!(
            "name = \"test\"\ndefault_site = \"plant\"\nstatus_every_s = 0.3\n\
             [zenoh]\nmode = \"client\"\nconnect = [\"{router}\"]\nhistory_windows = 0\n\
             {sections}"
        ),
    )
    .unwrap();
    let c = Command::new(bin())
        .args([
            "historian",
            "--summary-json",
            "--config",
            cfg.to_str().unwrap(),
        ])
        .envs(pg.env("fleet"))
        .env("RUST_LOG", "info")
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(dir.join("historian.log")).unwrap())
        .spawn()
        .unwrap();
    Guard(c)
}

/// SIGTERM, then the historian's last status (every loss range listed).
pub(crate) fn stop(mut g: Guard) -> HistorianStatus {
    // SAFETY: plain kill(2) on our own child.
    unsafe { libc::kill(g.0.id() as i32, libc::SIGTERM) };
    let mut out = String::new();
    g.0.stdout.take().unwrap().read_to_string(&mut out).unwrap();
    g.0.wait().unwrap();
    serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("last status {out:?}: {e}"))
}

/// Simulated points `<rig>-<i>/shaft/nde` of one run, each with a daemon's recent history
/// (keeping its `kept` windows) and a publisher with the fleet's congestion policy.
pub(crate) struct Points {
    rig: String,
    run_ns: u64,
    each: Vec<(RecentHistory, zenoh::pubsub::Publisher<'static>)>,
}

impl Points {
    pub(crate) fn declare(
        fleet: &zenoh::Session,
        rig: &str,
        run_ns: u64,
        kept: &[usize],
    ) -> Points {
        let each = kept
            .iter()
            .enumerate()
            .map(|(i, &kept)| {
                let base = format!("rigmon/{rig}-{i}/shaft/nde");
                let ring = RecentHistory::declare(fleet, &base, kept, Arc::default())
                    .unwrap()
                    .unwrap();
                let publisher = fleet
                    .declare_publisher(format!("{base}/health"))
                    .congestion_control(FLEET_CONGESTION)
                    .wait()
                    .unwrap();
                (ring, publisher)
            })
            .collect();
        Points {
            rig: rig.to_string(),
            run_ns,
            each,
        }
    }

    /// Window `seq` of every point: into its recent history, then published.
    pub(crate) fn put(&self, seq: u64) {
        for (i, (ring, publisher)) in self.each.iter().enumerate() {
            let mut m = every_field_set(self.run_ns, seq);
            m.rig = format!("{}-{i}", self.rig);
            m.publish_time_ns = now_ns();
            let json = serde_json::to_vec(&m).unwrap();
            ring.push(&json);
            publisher.put(json).wait().unwrap();
        }
    }
}

/// (point key, seq) of every window in the fleet database.
pub(crate) fn stored(
    rt: &tokio::runtime::Runtime,
    db: &tokio_postgres::Client,
) -> BTreeSet<(String, i64)> {
    rt.block_on(db.query(
        "SELECT p.key, w.seq FROM windows w JOIN points p USING (point_id)",
        &[],
    ))
    .unwrap()
    .iter()
    .map(|r| (r.get(0), r.get(1)))
    .collect()
}

/// Wait (up to 60 s) for the test historian's status to say its database is connected.
pub(crate) fn wait_connected(status: &std::sync::Mutex<Option<HistorianStatus>>) {
    wait_until("the historian's database", Duration::from_secs(60), || {
        status
            .lock()
            .unwrap()
            .as_ref()
            .is_some_and(|s| s.database.connected)
    });
}

#[test]
fn a_historian_slower_than_its_fleet_loses_nothing_in_silence() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let pg = Postgres::with_fleet_database();
    let (router_ep, _router) = loopback_router();
    let fleet = loopback_client(&router_ep);
    let (_status_sub, status) = historian_status(&fleet);
    let hist = slow_historian(d, &pg, &router_ep);
    wait_connected(&status);
    let points = Points::declare(&fleet, "bp", now_ns() - 120_000_000_000, &[KEPT; POINTS]);
    let put = |seq: u64| points.put(seq);
    put(1);
    let (rt, db) = pg.client("fleet");
    let stored = || stored(&rt, &db);
    wait_until(
        "window 1 of every point stored",
        Duration::from_secs(30),
        || stored().len() == POINTS,
    );

    // The database stalls: another session holds a lock on `windows` while the points
    // publish 390 windows (~600 KB) into a historian that keeps 50 in memory and ~64 KB on disk.
    let (lock_rt, locker) = pg.client("fleet");
    lock_rt
        .block_on(locker.batch_execute("BEGIN; LOCK TABLE windows IN ACCESS EXCLUSIVE MODE"))
        .unwrap();
    for seq in 2..=TICKS {
        put(seq);
        std::thread::sleep(Duration::from_millis(20));
    }
    wait_until(
        "the historian's buffer to drop",
        Duration::from_secs(20),
        || {
            status
                .lock()
                .unwrap()
                .as_ref()
                .is_some_and(|s| s.buffer.dropped > 0)
        },
    );
    lock_rt.block_on(locker.batch_execute("COMMIT")).unwrap();
    for seq in TICKS + 1..=TICKS + TAIL {
        std::thread::sleep(Duration::from_millis(500));
        put(seq);
    }
    wait_until(
        "the gaps asked of the points' recent history and the buffer written",
        Duration::from_secs(60),
        || {
            status.lock().unwrap().as_ref().is_some_and(|s| {
                let r = &s.recovery;
                s.buffer.memory + s.buffer.spilled == 0
                    && r.gaps > 0
                    && r.waiting + r.in_flight == 0
                    && r.recovered + r.lost + r.late >= r.requested
                    && stored().iter().filter(|(_, q)| *q > TICKS as i64).count()
                        >= POINTS * TAIL as usize
            })
        },
    );
    let last = stop(hist);
    check(&last, &stored(), d);
}

/// Every window 1..=TICKS of every point is in the database or in the ledger, never both.
fn check(last: &HistorianStatus, stored: &BTreeSet<(String, i64)>, dir: &Path) {
    let ledger: BTreeSet<(String, i64)> = last
        .lost
        .ranges
        .iter()
        .flat_map(|r| (r.first..=r.last).map(move |s| (r.point.clone(), s as i64)))
        .collect();
    assert_eq!(
        last.lost.ranges_left_off, 0,
        "the last status lists every range"
    );
    let mut unaccounted = Vec::new();
    for i in 0..POINTS {
        for seq in 1..=TICKS as i64 {
            let w = (format!("bp-{i}/shaft/nde"), seq);
            if !stored.contains(&w) && !ledger.contains(&w) {
                unaccounted.push(w);
            }
        }
    }
    assert!(
        unaccounted.is_empty(),
        "{} windows neither stored nor counted lost, e.g. {:?}; last status {last:?}",
        unaccounted.len(),
        &unaccounted[..unaccounted.len().min(5)]
    );
    let both: Vec<_> = ledger.intersection(stored).take(5).collect();
    assert!(both.is_empty(), "counted lost but stored: {both:?}");
    // The stall did make the historian drop, some of it came back from the points' recent
    // history, and what their rings no longer held is counted and logged by range.
    assert!(last.buffer.dropped > 0, "{:?}", last.buffer);
    assert!(last.recovery.recovered > 0, "{:?}", last.recovery);
    assert!(last.lost.windows > 0 && last.lost.windows == ledger.len() as u64);
    let log = std::fs::read_to_string(dir.join("historian.log")).unwrap();
    assert!(
        log.lines().any(|l| l.contains("lost: bp-")),
        "the log names the lost ranges: {log}"
    );
}
