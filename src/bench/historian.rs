//! `rigmon bench historian --points N --seconds S`: N simulated points at 2 windows/s through
//! a real Zenoh router (started here, loopback) into `rigmon historian` (a child process) and
//! the real PostgreSQL named by the standard `PG*` variables (password via `PGPASSFILE`), as
//! psql reads them. Reported: rows/s sustained, publish-to-committed latency p50/p99 (the
//! historian's own histogram, from each message's publish time to its commit), rows lost
//! (published minus rows in the database), CPU and RSS of the historian. Baseline in the same
//! run: the same rows written in-process by the historian's writer straight to the database
//! (no Zenoh, no buffer), so the ratio says how close the offered load is to what the database
//! path alone sustains. The points ([`super::historian_fleet`]) publish with the fleet's
//! congestion policy and answer their recent history as daemons do; every window is then in
//! the database, or counted lost by the historian (point and seq range), or counted by the
//! bench as put into a closed transport, or reported unaccounted (the failure).
//! The bench's rows are deleted at the end. Last line:
//! `historian: N points x 2 windows/s sustained, p99 publish-to-committed X s, L lost`.
//! Sustained: the publisher kept its clock, nothing was lost, and the windows that came live
//! were all committed within 2 s of the last publish (the historian keeps pace); the windows
//! recovered from recent history (each asked after the historian's grace period) and the
//! last decision on a missed window are reported beside it, not in the verdict.

use super::historian_fleet::{window, Fleet, RATE};
use super::{cpu_seconds, free_port, machine_line};
use crate::historian::database::{self, DatabaseSettings, Target};
use crate::historian::recovery::TAIL_SILENCE;
use crate::historian::row::WindowRow;
use crate::historian::status::HistorianStatus;
use crate::historian::writer::Writer;
use crate::publish::time_range::now_ns;
use crate::publish::zenoh::ZenohSettings;
use crate::vocabulary::ZenohMode;
use anyhow::{anyhow, bail, Context, Result};
use std::io::Read;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use zenoh::Wait;

/// Kills the historian if the bench fails half-way.
struct ChildGuard(Option<Child>);
impl Drop for ChildGuard {
    fn drop(&mut self) {
        if let Some(c) = self.0.as_mut() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Rows of the bench's points in the database, windows 1..=`ticks` (the measured ones).
async fn count_rows(c: &tokio_postgres::Client, tag: &str, ticks: u64) -> Result<i64> {
    Ok(c.query_one(
        "SELECT count(*) FROM windows w JOIN points p USING (point_id) WHERE p.key LIKE $1 AND w.seq <= $2",
        &[&format!("{tag}-%"), &(ticks as i64)],
    )
    .await?
    .get(0))
}

/// A window published live reaches the database with its publish time within this much of
/// its slot on the publishing clock (a tick's slices spread over 0.45 s, plus margin); one
/// recovered from a point's recent history was answered at least the historian's grace
/// period (1 s) plus one tick after its slot, so its publish time (the answer's) is later.
const LIVE_SLACK_S: f64 = 1.0;

/// Rows of windows 1..=`ticks` in the database: all of them, and those that came live (their
/// publish time within [`LIVE_SLACK_S`] of their slot on the clock that started at `t0_s`,
/// seconds since the Unix epoch), the rest being windows recovered from recent history.
async fn count_live(
    c: &tokio_postgres::Client,
    tag: &str,
    ticks: u64,
    t0_s: f64,
) -> Result<(i64, i64)> {
    let r = c
        .query_one(
            "SELECT count(*), count(*) FILTER (WHERE extract(epoch FROM w.publish_time)::float8 < $3::float8 + (w.seq - 1)::float8 / $4::float8 + $5::float8) \
             FROM windows w JOIN points p USING (point_id) WHERE p.key LIKE $1 AND w.seq <= $2",
            &[&format!("{tag}-%"), &(ticks as i64), &t0_s, &RATE, &LIVE_SLACK_S],
        )
        .await?;
    Ok((r.get(0), r.get(1)))
}

/// Remove everything the bench wrote (points named `<tag>-*`, site `<tag>`).
async fn clean(c: &tokio_postgres::Client, tag: &str) -> Result<()> {
    let like = format!("{tag}-%");
    let ids = "(SELECT point_id FROM points WHERE key LIKE $1)";
    for t in [
        "events",
        "point_latest",
        "point_status",
        "minutes",
        "windows",
    ] {
        c.execute(
            &format!("DELETE FROM {t} WHERE point_id IN {ids}"),
            &[&like],
        )
        .await?;
    }
    c.execute("DELETE FROM points WHERE key LIKE $1", &[&like])
        .await?;
    c.execute("DELETE FROM assets WHERE machine_id IN (SELECT machine_id FROM machines WHERE name LIKE $1)", &[&like]).await?;
    c.execute("DELETE FROM machines WHERE name LIKE $1", &[&like])
        .await?;
    c.execute("DELETE FROM sites WHERE name = $1", &[&tag])
        .await?;
    c.execute("DELETE FROM models WHERE name = 'bench' AND NOT EXISTS (SELECT 1 FROM windows w WHERE w.model_id = models.model_id)", &[]).await?;
    Ok(())
}

/// The database-only baseline: `points` x `ticks` rows written by the historian's own writer
/// in this process (the same binary COPY path and session settings, no Zenoh, no JSON
/// decode: the rows are made before the clock starts), rows/s. The first tick registers the
/// points and is not timed.
async fn baseline(
    target: &Target,
    tag: &str,
    points: usize,
    ticks: u64,
    max_rows: usize,
) -> Result<f64> {
    let (mut w, _) = Writer::open(target).await?;
    w.set_synchronous_commit(false).await?;
    let run = now_ns() - 3_600_000_000_000;
    let mut rows: Vec<WindowRow> = Vec::new();
    for seq in 1..=ticks {
        for i in 0..points {
            let mut m = window(tag, i, seq, run);
            m.publish_time_ns = now_ns();
            rows.push(WindowRow::parse(&serde_json::to_vec(&m)?, tag)?);
        }
    }
    let (first, rest) = rows.split_at_mut(points);
    w.write(first, &[]).await?;
    let t0 = Instant::now();
    for chunk in rest.chunks_mut(max_rows) {
        w.write(chunk, &[]).await?;
    }
    let rate = rest.len() as f64 / t0.elapsed().as_secs_f64();
    clean(w.client(), tag).await?;
    Ok(rate)
}

/// Which published windows are not in the database, and which of those the historian
/// counted as lost (its last status lists every range).
#[derive(Debug, Default, serde::Serialize)]
struct Missing {
    /// Not in the database.
    total: u64,
    /// ...of which in the historian's loss ledger (point and seq range),
    counted: u64,
    /// ...of which (not in the ledger) the bench put while its session had no router.
    no_route: u64,
    /// The first few not accounted for: `<point> seq <n>`.
    unaccounted_examples: Vec<String>,
}

/// Compare the database with what was published (`ticks` windows of each point).
async fn missing(
    c: &tokio_postgres::Client,
    tag: &str,
    points: usize,
    ticks: u64,
    lost: &crate::historian::losses::LostSummary,
    no_route: &std::collections::HashSet<(usize, u64)>,
) -> Result<Missing> {
    let rows = c
        .query(
            "SELECT p.key, w.seq FROM windows w JOIN points p USING (point_id) WHERE p.key LIKE $1",
            &[&format!("{tag}-%")],
        )
        .await?;
    let mut have: std::collections::HashMap<String, Vec<bool>> = Default::default();
    for r in &rows {
        let seq: i64 = r.get(1);
        let v = have
            .entry(r.get(0))
            .or_insert_with(|| vec![false; ticks as usize + 1]);
        if let Some(slot) = usize::try_from(seq).ok().and_then(|s| v.get_mut(s)) {
            *slot = true;
        }
    }
    let mut ledger: std::collections::HashMap<&str, Vec<(u64, u64)>> = Default::default();
    for r in &lost.ranges {
        ledger
            .entry(r.point.as_str())
            .or_default()
            .push((r.first, r.last));
    }
    let mut m = Missing::default();
    for i in 0..points {
        let key = format!("{tag}-{i}/shaft/nde");
        let got = have.get(&key);
        for seq in 1..=ticks {
            if got.is_some_and(|v| v[seq as usize]) {
                continue;
            }
            m.total += 1;
            let counted = ledger
                .get(key.as_str())
                .is_some_and(|rs| rs.iter().any(|&(f, l)| (f..=l).contains(&seq)));
            if counted {
                m.counted += 1;
            } else if no_route.contains(&(i, seq)) {
                m.no_route += 1;
            } else if m.unaccounted_examples.len() < 5 {
                m.unaccounted_examples.push(format!("{key} seq {seq}"));
            }
        }
    }
    Ok(m)
}

/// Results.
#[derive(Debug, serde::Serialize)]
struct Report {
    machine: String,
    points: usize,
    seconds: f64,
    published: u64,
    publisher_late_s: f64,
    rows_in_db: i64,
    /// Published and not in the database ...
    lost: i64,
    /// ... of which the historian counted by point and seq range (its status and log),
    lost_counted: u64,
    /// ... of which the bench put while its session had no router (a closed transport),
    lost_no_route: u64,
    /// ... and of which it said nothing.
    lost_unaccounted: u64,
    lost_unaccounted_examples: Vec<String>,
    /// Ranges in the historian's loss ledger.
    historian_lost_ranges: u64,
    /// Gaps the historian's tracker saw (windows that did not arrive live) ...
    gaps: u64,
    /// ... windows it asked the points' recent history for,
    requested: u64,
    /// ... windows it recovered from the points' recent history,
    recovered: u64,
    /// ... windows it asked again (their replies dropped on the way),
    asked_again: u64,
    /// ... and windows the simulated points answered from their recent history.
    answered_from_history: u64,
    /// Searches of the historian's database for holes, and the windows they found missing
    /// that no gap had named (a loss its gap tracker did not see).
    audits: u64,
    audit_found: u64,
    /// Publishing slices (10 per tick) in which the bench's session had no router.
    no_route_slices: u64,
    rows_per_s_offered: f64,
    rows_per_s_committed: f64,
    /// The last decision on a missed window (recovered or lost), s after the last publish.
    catch_up_s: f64,
    /// Every window that came live committed, s after the last publish (what "sustained"
    /// asks: the historian keeps pace with the fleet) ...
    live_rows_in_s: f64,
    /// ... and with those recovered from recent history (each waits the grace period first).
    all_rows_in_s: f64,
    /// The bench stopped waiting at its limit while the historian was still busy.
    wait_gave_up: bool,
    baseline_rows_per_s: f64,
    offered_over_baseline: f64,
    /// Committed while publishing over the database-only baseline.
    committed_over_baseline: f64,
    latency_p50_s: f64,
    latency_p99_s: f64,
    latency_max_s: f64,
    historian_cpu_percent: f64,
    historian_rss_mb: f64,
    historian_rss_peak_mb: f64,
    bench_cpu_percent: f64,
    dropped: u64,
    spilled: u64,
    sustained: bool,
    /// Where the historian's time went (whole run, wall seconds of each step).
    profile: crate::historian::status::Profile,
    /// The historian's COPY streams (`[batch] streams`) ...
    streams: usize,
    /// ... and the transactions it committed (batches; each one per stream).
    batches: u64,
}

fn status_mb(pid: u32, key: &str) -> f64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with(key))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// Windows of every point published after the measured ones (not counted): a daemon keeps
/// publishing, so a measured window dropped at the end shows as a gap like any other.
const TAIL_TICKS: u64 = 4;

/// The bench's historian searches its database for holes this often once it has caught up
/// (`[recovery] audit_every_s`; 300 s by default), so that the wait sees a search after the
/// last window came: every window is then stored or counted, whatever the gap tracker saw.
const AUDIT_EVERY_S: f64 = 4.0;

/// Start `rigmon historian` (this binary) as a Zenoh client of `endpoint`, its spill in `dir`.
fn start_historian(
    dir: &std::path::Path,
    tag: &str,
    endpoint: &str,
    streams: usize,
) -> Result<ChildGuard> {
    let cfg = dir.join("historian.toml");
    std::fs::write(
        &cfg,
        format!("name = \"{tag}\"\ndefault_site = \"{tag}\"\nstatus_every_s = 0.5\n[zenoh]\nmode = \"client\"\nconnect = [\"{endpoint}\"]\nhistory_windows = 0\n[buffer]\nspill_dir = \"spill\"\n[batch]\nstreams = {streams}\n[recovery]\naudit_every_s = {AUDIT_EVERY_S}\n"),
    )?;
    let child = Command::new(std::env::current_exe()?)
        .args(["historian", "--summary-json", "--config"])
        .arg(&cfg)
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(dir.join("historian.log"))?)
        .spawn()
        .context("starting rigmon historian")?;
    Ok(ChildGuard(Some(child)))
}

/// Stop the historian (SIGTERM) and read its last status (every loss range listed).
fn stop_historian(mut guard: ChildGuard) -> Result<HistorianStatus> {
    let mut child = guard.0.take().expect("child");
    // SAFETY: plain kill(2) on our own child.
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    let mut out = String::new();
    child.stdout.take().map(|mut s| s.read_to_string(&mut out));
    let _ = child.wait();
    serde_json::from_str(out.trim())
        .with_context(|| format!("the historian's last status: {out:?}"))
}

fn client_of(endpoint: &str) -> Result<zenoh::Session> {
    ZenohSettings {
        mode: ZenohMode::Client,
        connect: vec![endpoint.to_string()],
        history_windows: 0,
        ..Default::default()
    }
    .open()
}

/// What one run measured, before the report is made of it.
struct Measured {
    published: u64,
    publish_s: f64,
    late: f64,
    at_end: i64,
    catch_up: CatchUp,
    historian_cpu_s: f64,
    bench_cpu_s: f64,
    rss: (f64, f64),
    streams: usize,
}

/// Run the benchmark.
pub fn run(points: usize, streams: usize, seconds: f64, json: bool) -> Result<()> {
    if points == 0 || !(seconds >= 1.0) {
        bail!("--points must be at least 1 and --seconds at least 1");
    }
    let target = DatabaseSettings::default().resolve()?;
    let tag = format!("bench{}", std::process::id());
    database::block_on(async {
        let c = target.connect().await.context("bench historian needs the PostgreSQL named by PGHOST/PGPORT/PGUSER/PGDATABASE (password via PGPASSFILE)")?;
        clean(&c, &tag).await.ok();
        anyhow::Ok(())
    })??;
    let ticks = (seconds * RATE).round() as u64;
    let base_ticks = (40_000 / points.max(1)).clamp(3, 200) as u64;
    let base_tag = format!("{tag}base");
    let base_rate = database::block_on(baseline(&target, &base_tag, points, base_ticks, 20_000))??;
    let dir = tempfile::tempdir()?;
    let endpoint = format!("tcp/127.0.0.1:{}", free_port()?);
    let router = ZenohSettings {
        mode: ZenohMode::Router,
        listen: vec![endpoint.clone()],
        history_windows: 0,
        ..Default::default()
    }
    .open()?;
    let mut guard = start_historian(dir.path(), &tag, &endpoint, streams)?;
    let pid = guard.0.as_ref().map_or(0, Child::id);
    let publisher = client_of(&endpoint)?;
    let status_sub = publisher
        .declare_subscriber(format!("rigmon/@historian/{tag}/status"))
        .wait()
        .map_err(|e| anyhow!("{e}"))?;
    wait_ready(&status_sub, &mut guard, &dir.path().join("historian.log"))?;
    let mut fleet = Fleet::declare(&publisher, &tag, points, now_ns())?;
    fleet.wait_matched()?;
    let (cpu0, bench_cpu0) = (cpu_seconds(pid)?, cpu_seconds(std::process::id())?);
    let (t0, t0_s) = (Instant::now(), now_ns() as f64 / 1e9);
    let late = fleet.publish(t0, 1, ticks)?;
    let (end, publish_s) = (Instant::now(), t0.elapsed().as_secs_f64());
    let (cpu1, bench_cpu1) = (cpu_seconds(pid)?, cpu_seconds(std::process::id())?);
    let rss = (status_mb(pid, "VmRSS:"), status_mb(pid, "VmHWM:"));
    let at_end =
        database::block_on(async { count_rows(&target.connect().await?, &tag, ticks).await })??;
    let published = ticks * points as u64;
    let limit = Duration::from_secs_f64((seconds * 60.0).max(3600.0));
    let catch_up = tail_and_wait(
        &mut fleet,
        (&target, &tag, &status_sub),
        (ticks, published),
        (t0, t0_s, end, limit),
    )?;
    let last = stop_historian(guard)?;
    let (in_db, miss) = database::block_on(async {
        let c = target.connect().await?;
        let n = count_rows(&c, &tag, ticks).await?;
        let m = missing(&c, &tag, points, ticks, &last.lost, &fleet.no_route).await?;
        clean(&c, &tag).await?;
        anyhow::Ok((n, m))
    })??;
    let m = Measured {
        published,
        publish_s,
        late,
        at_end,
        catch_up,
        historian_cpu_s: cpu1 - cpu0,
        bench_cpu_s: bench_cpu1 - bench_cpu0,
        rss,
        streams,
    };
    let report = report(points, seconds, base_rate, &m, in_db, miss, &last, &fleet);
    if report.lost_unaccounted > 0 {
        keep_evidence(dir.path(), &tag, &last)?;
    }
    drop(fleet);
    let _ = publisher.close().wait();
    let _ = router.close().wait();
    print(&report, json)
}

/// Publish the tail ticks while waiting for the historian to catch up. Late is allowed, lost
/// is not: the wait goes on while the historian still moves (it ends 3 s past the tail
/// silence after it stops), however long its backlog and its asks take (up to `limit`), so
/// that every window ends in the database or in its loss ledger; the tail is published
/// meanwhile, so the first count comes 0.2 s after the end, not after it.
fn tail_and_wait(
    fleet: &mut Fleet,
    (target, tag, status_sub): (&Target, &str, &StatusSub),
    (ticks, published): (u64, u64),
    (t0, t0_s, end, limit): (Instant, f64, Instant, Duration),
) -> Result<CatchUp> {
    let (tail, catch_up) = std::thread::scope(|sc| {
        let tail = sc.spawn(|| fleet.publish(t0, ticks + 1, ticks + TAIL_TICKS));
        let catch_up = database::block_on(wait_caught_up(
            target,
            tag,
            (ticks, published, t0_s),
            status_sub,
            (end, limit),
        ));
        (tail.join(), catch_up)
    });
    tail.map_err(|_| anyhow!("the bench's tail publisher panicked"))??;
    catch_up?
}

/// Windows went missing unaccounted (the failure): keep the historian's log and last status
/// in the current folder for whoever looks into it.
fn keep_evidence(dir: &std::path::Path, tag: &str, last: &HistorianStatus) -> Result<()> {
    let keep = std::env::current_dir()?.join(format!("{tag}-historian.log"));
    std::fs::copy(dir.join("historian.log"), &keep)
        .with_context(|| format!("keeping the historian's log as {}", keep.display()))?;
    std::fs::write(
        keep.with_extension("status.json"),
        serde_json::to_vec_pretty(last)?,
    )?;
    eprintln!(
        "windows went missing unaccounted: the historian's log is kept as {} (and its last status beside it)",
        keep.display()
    );
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn report(
    points: usize,
    seconds: f64,
    base_rate: f64,
    m: &Measured,
    in_db: i64,
    miss: Missing,
    last: &HistorianStatus,
    fleet: &Fleet,
) -> Report {
    let wall = m.publish_s;
    let lost = m.published as i64 - in_db;
    let unaccounted = miss.total - miss.counted - miss.no_route;
    Report {
        machine: machine_line(),
        points,
        seconds,
        published: m.published,
        publisher_late_s: m.late,
        rows_in_db: in_db,
        lost,
        lost_counted: miss.counted,
        lost_no_route: miss.no_route,
        lost_unaccounted: unaccounted,
        lost_unaccounted_examples: miss.unaccounted_examples,
        historian_lost_ranges: last.lost.ranges.len() as u64 + last.lost.ranges_left_off,
        gaps: last.recovery.gaps,
        requested: last.recovery.requested,
        profile: last.profile,
        streams: m.streams,
        batches: last.rows.batches,
        recovered: last.recovery.recovered,
        asked_again: last.recovery.asked_again,
        answered_from_history: fleet.answered.load(std::sync::atomic::Ordering::Relaxed),
        audits: last.recovery.audits,
        audit_found: last.recovery.audit_found,
        no_route_slices: fleet.no_route_slices,
        rows_per_s_offered: m.published as f64 / wall,
        rows_per_s_committed: m.at_end as f64 / wall,
        catch_up_s: m.catch_up.decisions_s,
        live_rows_in_s: m.catch_up.live_rows_s,
        all_rows_in_s: m.catch_up.rows_s,
        wait_gave_up: m.catch_up.gave_up,
        baseline_rows_per_s: base_rate,
        offered_over_baseline: (m.published as f64 / wall) / base_rate,
        committed_over_baseline: (m.at_end as f64 / wall) / base_rate,
        latency_p50_s: last.latency.p50_s,
        latency_p99_s: last.latency.p99_s,
        latency_max_s: last.latency.max_s,
        historian_cpu_percent: 100.0 * m.historian_cpu_s / wall,
        historian_rss_mb: m.rss.0,
        historian_rss_peak_mb: m.rss.1,
        bench_cpu_percent: 100.0 * m.bench_cpu_s / wall,
        dropped: last.buffer.dropped,
        spilled: last.buffer.spilled_total,
        sustained: lost == 0 && m.catch_up.live_rows_s < 2.0 && m.late < 1.0,
    }
}

/// When the rows were in after the last publish (s), from the counts taken while waiting.
#[derive(Debug, Clone, Copy)]
struct CatchUp {
    /// The windows that came live all committed (their count reached its final value).
    live_rows_s: f64,
    /// All rows, the recovered ones too.
    rows_s: f64,
    /// The wait's end: the last decision on a missed window.
    decisions_s: f64,
    /// The wait reached its limit with the historian still busy (rows missing then are not
    /// decided, not lost).
    gave_up: bool,
}

impl CatchUp {
    /// From `(s after the end, all rows, live rows)` counts in time order; a count that
    /// never moved is in at its first sample.
    fn of(counts: &[(f64, i64, i64)], decisions_s: f64, gave_up: bool) -> CatchUp {
        let (_, all, live) = counts.last().copied().unwrap_or((0.0, 0, 0));
        let first = |reached: &dyn Fn(&(f64, i64, i64)) -> bool| {
            counts.iter().find(|c| reached(c)).map_or(0.0, |c| c.0)
        };
        CatchUp {
            live_rows_s: first(&|c| c.2 >= live),
            rows_s: first(&|c| c.1 >= all),
            decisions_s,
            gave_up,
        }
    }
}

type StatusSub =
    zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>;

/// After the last publish: wait until every row is in the database, or the historian has
/// nothing left to write (buffer and spill empty, nothing received and nothing committed for
/// 3 s: the rest is lost and its ledger says which), at most `limit` after `end` (the last
/// measured publish). Messages still on their way through Zenoh count as received only when
/// they arrive, so a historian that is receiving, or asking for missed windows, is waited
/// for. Returns when the windows that came live were all in, when all rows were, and when
/// the wait ended (the last decision), each in seconds since `end`.
async fn wait_caught_up(
    target: &Target,
    tag: &str,
    (ticks, published, t0_s): (u64, u64, f64),
    status: &StatusSub,
    (end, limit): (Instant, Duration),
) -> Result<CatchUp> {
    let c = target.connect().await?;
    let (mut n, mut last, mut still_since) = (0, [0u64; 4], Instant::now());
    let mut audits_then = u64::MAX;
    let mut counts: Vec<(f64, i64, i64)> = Vec::new();
    let bar = indicatif::ProgressBar::new(published).with_style(
        indicatif::ProgressStyle::with_template(
            "catching up {bar:30} {pos}/{len} rows {elapsed} {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    while (n as u64) < published && end.elapsed() < limit {
        tokio::time::sleep(Duration::from_millis(200)).await;
        let (all, live) = count_live(&c, tag, ticks, t0_s).await?;
        n = all;
        counts.push((end.elapsed().as_secs_f64(), all, live));
        bar.set_position(all.max(0) as u64);
        let mut latest = None;
        while let Ok(Some(sample)) = status.try_recv() {
            latest = serde_json::from_slice::<HistorianStatus>(&sample.payload().to_bytes()).ok();
        }
        if let Some(st) = latest {
            let r = &st.recovery;
            let progress = [
                st.rows.committed,
                st.received.health,
                r.requested,
                r.recovered + r.lost + r.late + r.backfilled + r.not_backfilled,
            ];
            let busy = st.buffer.memory + st.buffer.spilled + r.waiting + r.in_flight > 0;
            bar.set_message(format!(
                "(buffered {}, spilled {}, to ask {}, asks out {}, lost {})",
                st.buffer.memory, st.buffer.spilled, r.waiting, r.in_flight, r.lost
            ));
            if progress != last || busy {
                (last, still_since) = (progress, Instant::now());
                audits_then = r.audits + u64::from(r.auditing);
            } else if still_since.elapsed() > TAIL_SILENCE + Duration::from_secs(3)
                && r.audits > audits_then
                && !r.auditing
            {
                // still for longer than the historian waits before it asks a silent
                // point's tail, so the tails it asks are in, and its database searched for
                // holes since (an audit every AUDIT_EVERY_S once it has caught up)
                break;
            }
        }
    }
    bar.finish_and_clear();
    let gave_up = (n as u64) < published && end.elapsed() >= limit;
    Ok(CatchUp::of(&counts, end.elapsed().as_secs_f64(), gave_up))
}

/// Wait for the historian's first status saying its database is connected.
fn wait_ready(sub: &StatusSub, guard: &mut ChildGuard, log: &std::path::Path) -> Result<()> {
    let t = Instant::now();
    while t.elapsed() < Duration::from_secs(60) {
        if let Some(c) = guard.0.as_mut() {
            if let Some(s) = c.try_wait()? {
                let err = std::fs::read_to_string(log).unwrap_or_default();
                bail!("rigmon historian exited ({s}) before it was ready: {err}");
            }
        }
        if let Ok(Some(sample)) = sub.recv_timeout(Duration::from_millis(200)) {
            let st: HistorianStatus = serde_json::from_slice(&sample.payload().to_bytes())?;
            if st.database.connected {
                return Ok(());
            }
        }
    }
    bail!("the historian did not report a database connection within 60 s")
}

fn print(r: &Report, json: bool) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string(r)?);
    } else {
        println!("machine: {}", r.machine);
        println!("offered: {} points x {RATE} windows/s for {:.1} s = {} rows ({:.0} rows/s; publisher late by at most {:.3} s)", r.points, r.seconds, r.published, r.rows_per_s_offered, r.publisher_late_s);
        println!("committed while publishing: {:.0} rows/s; after the last publish the windows that came live were all committed in {:.2} s, with those recovered from recent history in {:.2} s, the last decision on a missed window came at {:.2} s", r.rows_per_s_committed, r.live_rows_in_s, r.all_rows_in_s, r.catch_up_s);
        println!("database alone (the historian's writer in this process, same binary COPY, no Zenoh, no decode): {:.0} rows/s; offered = {:.2} x, committed while publishing = {:.2} x that", r.baseline_rows_per_s, r.offered_over_baseline, r.committed_over_baseline);
        println!(
            "publish-to-committed: p50 {:.3} s, p99 {:.3} s, max {:.3} s",
            r.latency_p50_s, r.latency_p99_s, r.latency_max_s
        );
        println!("historian: CPU {:.1} % of one core, RSS {:.1} MB (peak {:.1} MB); bench process (router + publishers) CPU {:.1} %", r.historian_cpu_percent, r.historian_rss_mb, r.historian_rss_peak_mb, r.bench_cpu_percent);
        println!(
            "rows in the database {} of {} published; spilled to disk {}, dropped by the historian's buffer {}",
            r.rows_in_db, r.published, r.spilled, r.dropped
        );
        println!("missed live (congestion policy Drop): the historian saw {} gaps, asked for {} windows (again {}: replies dropped on the way) and recovered {} from the points' recent history ({} answered); the bench had no router in {} publishing slices", r.gaps, r.requested, r.asked_again, r.recovered, r.answered_from_history, r.no_route_slices);
        println!("audits of the historian's database: {}, windows found missing that no gap named {} (asked for, or counted lost)", r.audits, r.audit_found);
        let p = &r.profile;
        println!("historian's time (whole run, wall s): zenoh callbacks {:.1}, buffer take (spill reads) {:.1}, decode {:.1}, write (COPY + insert + commit, database included) {:.1}; {} batches (mean {:.0} rows) over {} COPY streams", p.intake_s, p.take_s, p.decode_s, p.write_s, r.batches, r.rows_in_db as f64 / r.batches.max(1) as f64, r.streams);
        println!(
            "not in the database {}: counted lost by the historian with point and seq range {} ({} ranges in its status), put by the bench into a closed transport {}, not accounted for {}{}",
            r.lost,
            r.lost_counted,
            r.historian_lost_ranges,
            r.lost_no_route,
            r.lost_unaccounted,
            if r.lost_unaccounted_examples.is_empty() {
                String::new()
            } else {
                format!(" (e.g. {})", r.lost_unaccounted_examples.join(", "))
            }
        );
    }
    if r.wait_gave_up {
        println!("the bench stopped waiting {:.0} s after the end with the historian still busy: the rows not in the database were not yet decided (stored, or counted lost by range), so 'not accounted for' counts undecided ones too", r.catch_up_s);
    }
    let lost = format!(
        "{} lost ({} counted by point and seq range, {} into a closed transport, {} unaccounted)",
        r.lost, r.lost_counted, r.lost_no_route, r.lost_unaccounted
    );
    if r.sustained {
        println!("historian: {} points x 2 windows/s sustained, p99 publish-to-committed {:.2} s, {lost}", r.points, r.latency_p99_s);
    } else {
        println!("historian: {} points x 2 windows/s NOT sustained (the live windows all in {:.1} s after the end, publisher late by {:.1} s), p99 publish-to-committed {:.2} s, {lost}", r.points, r.live_rows_in_s, r.publisher_late_s, r.latency_p99_s);
    }
    Ok(())
}
