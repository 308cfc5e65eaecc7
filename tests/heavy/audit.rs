//! Issue 40: the historian's audit of its own database finds a window missing that no gap
//! named, whatever the reason, and asks for it or counts it. Real parts: a PostgreSQL started
//! here, a Zenoh router in this process (loopback, explicit endpoints, multicast scouting
//! off), the built `rigmon historian`, and points that keep the daemon's own recent history
//! (`rigmon::publish::recent::RecentHistory`). The windows are stored whole; then rows are
//! deleted behind the historian's back (a loss its gap tracker cannot see): inside a run, a
//! run's first windows, and one the point's recent history no longer holds. The audit must
//! bring back the first two and count the third by point and seq range, and say so.

use super::backpressure::{now_ns, stop, stored, test_historian, wait_connected, Points};
use super::historian::{
    historian_status, loopback_client, loopback_router, wait_until, Guard, Postgres,
};
use std::path::Path;
use std::time::Duration;

const TICKS: u64 = 30;
/// Windows each point's recent history keeps: the first two points hold all, the third only
/// its last 10.
const KEPT: [usize; 3] = [100, 100, 10];

/// A historian that audits its database every second once it has caught up.
fn auditing_historian(dir: &Path, pg: &Postgres, router: &str) -> Guard {
    test_historian(
        dir,
        pg,
        router,
        "[buffer]\nspill_dir = \"spill\"\n[batch]\nmax_delay_ms = 100\n\
         [recovery]\nquery_timeout_s = 5.0\naudit_every_s = 1.0\n",
    )
}

#[test]
fn windows_missing_behind_the_historians_back_are_found_asked_for_or_counted() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let pg = Postgres::with_fleet_database();
    let (router_ep, _router) = loopback_router();
    let fleet = loopback_client(&router_ep);
    let (_status_sub, status) = historian_status(&fleet);
    let hist = auditing_historian(d, &pg, &router_ep);
    wait_connected(&status);
    // The run begins after the historian listens: its first windows count.
    let points = Points::declare(&fleet, "au", now_ns(), &KEPT);
    for seq in 1..=TICKS {
        points.put(seq);
        std::thread::sleep(Duration::from_millis(20));
    }
    let (rt, db) = pg.client("fleet");
    let stored = || stored(&rt, &db);
    let all = KEPT.len() * TICKS as usize;
    wait_until("every window stored", Duration::from_secs(30), || {
        stored().len() == all
    });
    let before = status.lock().unwrap().as_ref().unwrap().recovery;
    assert_eq!(before.audit_found, 0, "nothing missing yet: {before:?}");

    // Behind the historian's back: window 5-7 of point 0, the first two of point 1, and
    // window 3 of point 2 (whose recent history holds 21-30 only).
    let gone: [(&str, i64, i64); 3] = [("au-0", 5, 7), ("au-1", 1, 2), ("au-2", 3, 3)];
    for (rig, first, last) in gone {
        let n = rt
            .block_on(db.execute(
                "DELETE FROM windows w USING points p WHERE p.point_id = w.point_id
                 AND p.key = $1 AND w.seq BETWEEN $2 AND $3",
                &[&format!("{rig}/shaft/nde"), &first, &last],
            ))
            .unwrap();
        assert_eq!(n, (last - first + 1) as u64);
    }
    wait_until(
        "the audit's holes asked for and decided",
        Duration::from_secs(60),
        || {
            let decided = status.lock().unwrap().as_ref().is_some_and(|s| {
                let r = &s.recovery;
                r.audit_found >= 6 && r.waiting + r.in_flight == 0 && s.lost.windows >= 1
            });
            // what came back is written after its request ends
            decided && stored().len() == all - 1
        },
    );
    let have = stored();
    let last = stop(hist);
    if std::env::var_os("RIGMON_SHOW_LOG").is_some() {
        eprintln!(
            "{}",
            std::fs::read_to_string(d.join("historian.log")).unwrap()
        );
    }
    let r = &last.recovery;
    assert_eq!(
        r.audit_found, 6,
        "found once each, the lost one not asked again: {r:?}"
    );
    assert!(r.audits >= 2, "at start and after: {r:?}");
    let back: Vec<_> = [
        ("au-0", 5),
        ("au-0", 6),
        ("au-0", 7),
        ("au-1", 1),
        ("au-1", 2),
    ]
    .iter()
    .filter(|(rig, seq)| !have.contains(&(format!("{rig}/shaft/nde"), *seq)))
    .collect();
    assert!(back.is_empty(), "not brought back: {back:?}; {r:?}");
    assert_eq!(have.len(), all - 1, "all but window 3 of au-2");
    let ledger: Vec<_> = last
        .lost
        .ranges
        .iter()
        .map(|l| (l.point.as_str(), l.first, l.last))
        .collect();
    assert_eq!(ledger, [("au-2/shaft/nde", 3, 3)], "{:?}", last.lost);
    let log = std::fs::read_to_string(d.join("historian.log")).unwrap();
    assert!(
        log.lines()
            .any(|l| l.contains("audit:") && l.contains("no gap named")),
        "the log says what the audit found: {log}"
    );
}
