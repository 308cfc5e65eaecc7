//! `rigmon bench historian --points N --seconds S`: N simulated points at 2 windows/s through
//! a real Zenoh router (started here, loopback) into `rigmon historian` (a child process) and
//! the real PostgreSQL named by the standard `PG*` variables (password via `PGPASSFILE`), as
//! psql reads them. Reported: rows/s sustained, publish-to-committed latency p50/p99 (the
//! historian's own histogram, from each message's publish time to its commit), rows lost
//! (published minus rows in the database), CPU and RSS of the historian. Baseline in the same
//! run: the same rows written in-process by the historian's writer straight to the database
//! (no Zenoh, no buffer), so the ratio says how close the offered load is to what the database
//! path alone sustains. The bench's rows are deleted at the end. Last line:
//! `historian: N points x 2 windows/s sustained, p99 publish-to-committed X s, L lost`.

use super::{cpu_seconds, free_port, machine_line};
use crate::health::iso20816::Zone;
use crate::health::Basis;
use crate::historian::database::{self, DatabaseSettings, Target};
use crate::historian::row::WindowRow;
use crate::historian::status::HistorianStatus;
use crate::historian::writer::Writer;
use crate::model::evidence::FamilyEvidence;
use crate::publish::time_range::now_ns;
use crate::publish::zenoh::ZenohSettings;
use crate::vocabulary::Condition;
use crate::vocabulary::ZenohMode;
use crate::wire::health::{
    FaultBands, HealthMessage, ModelInfo, QualityReport, WindowTimes, SCHEMA, SCHEMA_VERSION,
};
use anyhow::{anyhow, bail, Context, Result};
use std::io::Read;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use zenoh::qos::CongestionControl;
use zenoh::Wait;

/// Windows per second per point (the daemon's hop of 0.5 s).
const RATE: f64 = 2.0;

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

/// One simulated window of point `i`, window number `seq` of a run starting at `run_ns`.
fn window(tag: &str, i: usize, seq: u64, run_ns: u64) -> HealthMessage {
    let labels: Vec<String> = Condition::NAMES.iter().map(|s| s.to_string()).collect();
    let end_s = seq as f64 / RATE + 0.5;
    let wobble = ((seq as f64 * 0.37 + i as f64).sin() * 0.1) as f32;
    let probs = [
        0.85 + wobble,
        0.05,
        0.05 - wobble / 2.0,
        0.05 - wobble / 2.0,
    ];
    HealthMessage {
        schema: SCHEMA.into(),
        schema_version: SCHEMA_VERSION,
        rig: format!("{tag}-{i}"),
        asset: "shaft".into(),
        point: "nde".into(),
        site: Some(tag.to_string()),
        seq,
        window: WindowTimes {
            start_s: end_s - 1.0,
            end_s,
            start_ns: run_ns + ((end_s - 1.0) * 1e9) as u64,
            end_ns: run_ns + (end_s * 1e9) as u64,
        },
        publish_time_ns: 0,
        rpm: Some(1480.0 + 10.0 * f64::from(wobble)),
        speed_source: crate::vocabulary::SpeedSourceKind::Tacho,
        speed_confidence: None,
        speed_rival_rpm: None,
        quality: QualityReport {
            ok: true,
            ..Default::default()
        },
        probabilities: labels.iter().cloned().zip(probs).collect(),
        window_state: labels[0].clone(),
        unknown_reason: None,
        alarm_despite: None,
        decision: Basis::Model,
        overruled: None,
        evidence: Some(FamilyEvidence {
            outer_race: 0.4 + wobble,
            inner_race: -0.2,
            ball: 0.1 - wobble,
        }),
        impulse: None,
        indicators: None,
        state: labels[0].clone(),
        state_since_s: 0.5,
        state_changed: seq == 1,
        confidence: probs[0],
        novelty: 0.3 + wobble,
        novelty_threshold: 1.0,
        baseline_distance: None,
        beyond_baseline: None,
        fault_bands: FaultBands {
            channel: "vertical".into(),
            orders: [
                ("bpfo".to_string(), 3.58),
                ("bpfi".to_string(), 5.42),
                ("two_bsf".to_string(), 4.71),
            ]
            .into(),
            bpfo: vec![0.02 + wobble.abs() / 10.0, 0.01, 0.005],
            bpfi: vec![0.01, 0.008, 0.004],
            two_bsf: vec![0.006, 0.004, 0.002],
            floor: 0.003,
        },
        velocity_rms_mm_s: Some(1.8 + f64::from(wobble)),
        iso_zone: Some(Zone::B),
        model: ModelInfo {
            id: "bench".into(),
            sha256: "0".repeat(64),
            labels,
            foreign: Vec::new(),
        },
        calibration_id: None,
        software_version: env!("CARGO_PKG_VERSION").to_string(),
    }
}

/// Rows of the bench's points in the database.
async fn count_rows(c: &tokio_postgres::Client, tag: &str) -> Result<i64> {
    Ok(c.query_one(
        "SELECT count(*) FROM windows w JOIN points p USING (point_id) WHERE p.key LIKE $1",
        &[&format!("{tag}-%")],
    )
    .await?
    .get(0))
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
    /// ...of which in the historian's loss ledger (point and seq range).
    counted: u64,
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
    /// ... and of which it said nothing.
    lost_unaccounted: u64,
    lost_unaccounted_examples: Vec<String>,
    /// Ranges in the historian's loss ledger.
    historian_lost_ranges: u64,
    rows_per_s_offered: f64,
    rows_per_s_committed: f64,
    catch_up_s: f64,
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

/// Run the benchmark.
pub fn run(points: usize, seconds: f64, json: bool) -> Result<()> {
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
    let port = free_port()?;
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let router = ZenohSettings {
        mode: ZenohMode::Router,
        listen: vec![endpoint.clone()],
        history_windows: 0,
        ..Default::default()
    }
    .open()?;
    let cfg = dir.path().join("historian.toml");
    std::fs::write(
        &cfg,
        format!("name = \"{tag}\"\ndefault_site = \"{tag}\"\nstatus_every_s = 0.5\n[zenoh]\nmode = \"client\"\nconnect = [\"{endpoint}\"]\nhistory_windows = 0\n[buffer]\nspill_dir = \"spill\"\n"),
    )?;
    let exe = std::env::current_exe()?;
    let log = dir.path().join("historian.log");
    let child = Command::new(exe)
        .args(["historian", "--summary-json", "--config"])
        .arg(&cfg)
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(&log)?)
        .spawn()
        .context("starting rigmon historian")?;
    let pid = child.id();
    let mut guard = ChildGuard(Some(child));
    let publisher = ZenohSettings {
        mode: ZenohMode::Client,
        connect: vec![endpoint.clone()],
        history_windows: 0,
        ..Default::default()
    }
    .open()?;
    let status_key = format!("rigmon/@historian/{tag}/status");
    let status_sub = publisher
        .declare_subscriber(status_key.clone())
        .wait()
        .map_err(|e| anyhow!("{e}"))?;
    wait_ready(&status_sub, &mut guard, &log)?;
    let pubs = (0..points)
        .map(|i| {
            publisher
                .declare_publisher(format!("rigmon/{tag}-{i}/shaft/nde/health"))
                .congestion_control(CongestionControl::Block)
                .wait()
                .map_err(|e| anyhow!("{e}"))
        })
        .collect::<Result<Vec<_>>>()?;
    let wait_match = Instant::now();
    while !pubs[0]
        .matching_status()
        .wait()
        .map(|m| m.matching())
        .unwrap_or(false)
    {
        if wait_match.elapsed() > Duration::from_secs(20) {
            bail!("the historian never subscribed to rigmon/**/health");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let run_ns = now_ns();
    let (cpu0, bench_cpu0) = (cpu_seconds(pid)?, cpu_seconds(std::process::id())?);
    let t0 = Instant::now();
    let mut late = 0.0f64;
    const SLICES: usize = 10;
    for seq in 1..=ticks {
        for s in 0..SLICES {
            let due = Duration::from_secs_f64(
                (seq - 1) as f64 / RATE + s as f64 / (RATE * SLICES as f64),
            );
            match due.checked_sub(t0.elapsed()) {
                Some(wait) => std::thread::sleep(wait),
                None => late = late.max((t0.elapsed() - due).as_secs_f64()),
            }
            for i in (s..points).step_by(SLICES) {
                let mut m = window(&tag, i, seq, run_ns);
                m.publish_time_ns = now_ns();
                pubs[i]
                    .put(serde_json::to_vec(&m)?)
                    .wait()
                    .map_err(|e| anyhow!("{e}"))?;
            }
        }
    }
    let published = ticks * points as u64;
    let publish_s = t0.elapsed().as_secs_f64();
    let (cpu1, bench_cpu1) = (cpu_seconds(pid)?, cpu_seconds(std::process::id())?);
    let (rss, peak) = (status_mb(pid, "VmRSS:"), status_mb(pid, "VmHWM:"));
    let limit = Duration::from_secs_f64(seconds.max(60.0) * 3.0);
    let (at_end, catch_up) =
        database::block_on(wait_caught_up(&target, &tag, published, &status_sub, limit))??;
    // SAFETY: plain kill(2) on our own child.
    unsafe { libc::kill(pid as i32, libc::SIGTERM) };
    let mut child = guard.0.take().expect("child");
    let mut out = String::new();
    child.stdout.take().map(|mut s| s.read_to_string(&mut out));
    let _ = child.wait();
    let last: HistorianStatus = serde_json::from_str(out.trim())
        .with_context(|| format!("the historian's last status: {out:?}"))?;
    let (in_db, miss) = database::block_on(async {
        let c = target.connect().await?;
        let n = count_rows(&c, &tag).await?;
        let m = missing(&c, &tag, points, ticks, &last.lost).await?;
        clean(&c, &tag).await?;
        anyhow::Ok((n, m))
    })??;
    drop(pubs);
    let _ = publisher.close().wait();
    let _ = router.close().wait();
    let wall = publish_s;
    let lost = published as i64 - in_db;
    let unaccounted = miss.total - miss.counted;
    let report = Report {
        machine: machine_line(),
        points,
        seconds,
        published,
        publisher_late_s: late,
        rows_in_db: in_db,
        lost,
        lost_counted: miss.counted,
        lost_unaccounted: unaccounted,
        lost_unaccounted_examples: miss.unaccounted_examples,
        historian_lost_ranges: last.lost.ranges.len() as u64 + last.lost.ranges_left_off,
        rows_per_s_offered: published as f64 / wall,
        rows_per_s_committed: at_end as f64 / wall,
        catch_up_s: catch_up,
        baseline_rows_per_s: base_rate,
        offered_over_baseline: (published as f64 / wall) / base_rate,
        committed_over_baseline: (at_end as f64 / wall) / base_rate,
        latency_p50_s: last.latency.p50_s,
        latency_p99_s: last.latency.p99_s,
        latency_max_s: last.latency.max_s,
        historian_cpu_percent: 100.0 * (cpu1 - cpu0) / wall,
        historian_rss_mb: rss,
        historian_rss_peak_mb: peak,
        bench_cpu_percent: 100.0 * (bench_cpu1 - bench_cpu0) / wall,
        dropped: last.buffer.dropped,
        spilled: last.buffer.spilled_total,
        sustained: lost == 0 && catch_up < 2.0 && late < 1.0,
    };
    print(&report, json)
}

type StatusSub =
    zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>;

/// After the last publish: wait until every row is in the database, or the historian has
/// nothing left to write (buffer and spill empty, nothing received and nothing committed for
/// 3 s: the rest is lost and its ledger says which), at most `limit`. Messages still on their
/// way through Zenoh count as received only when they arrive, so a historian that is
/// receiving is waited for. Returns (rows in the database when
/// publishing ended, seconds waited).
async fn wait_caught_up(
    target: &Target,
    tag: &str,
    published: u64,
    status: &StatusSub,
    limit: Duration,
) -> Result<(i64, f64)> {
    let c = target.connect().await?;
    let at_end = count_rows(&c, tag).await?;
    let t = Instant::now();
    let (mut n, mut last, mut still_since) = (at_end, (0u64, 0u64), Instant::now());
    while (n as u64) < published && t.elapsed() < limit {
        tokio::time::sleep(Duration::from_millis(200)).await;
        n = count_rows(&c, tag).await?;
        let mut latest = None;
        while let Ok(Some(sample)) = status.try_recv() {
            latest = serde_json::from_slice::<HistorianStatus>(&sample.payload().to_bytes()).ok();
        }
        if let Some(st) = latest {
            let progress = (st.rows.committed, st.received.health);
            if progress != last || st.buffer.memory + st.buffer.spilled > 0 {
                (last, still_since) = (progress, Instant::now());
            } else if still_since.elapsed() > Duration::from_secs(3) {
                break;
            }
        }
    }
    Ok((at_end, t.elapsed().as_secs_f64()))
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
        println!("committed while publishing: {:.0} rows/s; all committed {:.2} s after the last publish", r.rows_per_s_committed, r.catch_up_s);
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
        println!(
            "not in the database {}: counted lost by the historian with point and seq range {} ({} ranges in its status), not accounted for {}{}",
            r.lost,
            r.lost_counted,
            r.historian_lost_ranges,
            r.lost_unaccounted,
            if r.lost_unaccounted_examples.is_empty() {
                String::new()
            } else {
                format!(" (e.g. {})", r.lost_unaccounted_examples.join(", "))
            }
        );
    }
    let lost = format!(
        "{} lost ({} counted by point and seq range, {} unaccounted)",
        r.lost, r.lost_counted, r.lost_unaccounted
    );
    if r.sustained {
        println!("historian: {} points x 2 windows/s sustained, p99 publish-to-committed {:.2} s, {lost}", r.points, r.latency_p99_s);
    } else {
        println!("historian: {} points x 2 windows/s NOT sustained (caught up {:.1} s after the end), p99 publish-to-committed {:.2} s, {lost}", r.points, r.catch_up_s, r.latency_p99_s);
    }
    Ok(())
}
