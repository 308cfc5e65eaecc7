//! The simulated fleet of `rigmon bench historian`: N points publishing health at 2
//! windows/s on one client session, with the fleet's congestion policy
//! ([`FLEET_CONGESTION`]), each answering its recent history as a daemon does
//! (`<base>/recent?run=..;seq=[a..b]|[c..d]`; regenerated on demand, since every window is a function
//! of point, seq and run, so 10,000 points need no 1.8 GB ring), and noting every window it
//! put while its session had no router (sent into a closed transport: the bench counts those
//! itself, by point and seq).

use crate::health::iso20816::Zone;
use crate::health::Basis;
use crate::model::evidence::FamilyEvidence;
use crate::publish::recent::{same_run, Held, RecentQuery, SUFFIX};
use crate::publish::time_range::now_ns;
use crate::publish::zenoh::FLEET_CONGESTION;
use crate::vocabulary::Condition;
use crate::wire::health::{
    FaultBands, HealthMessage, ModelInfo, QualityReport, WindowTimes, SCHEMA, SCHEMA_VERSION,
};
use anyhow::{anyhow, bail, Result};
use std::collections::HashSet;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use zenoh::Wait;

/// Windows per second per point (the daemon's hop of 0.5 s).
pub(super) const RATE: f64 = 2.0;

/// One simulated window of point `i`, window number `seq` of a run starting at `run_ns`.
pub(super) fn window(tag: &str, i: usize, seq: u64, run_ns: u64) -> HealthMessage {
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

/// The points of one bench run on one session.
pub(super) struct Fleet {
    session: zenoh::Session,
    tag: String,
    run_ns: u64,
    pubs: Vec<zenoh::pubsub::Publisher<'static>>,
    /// Highest seq put per point (what its recent history may answer).
    published: Arc<Vec<AtomicU64>>,
    /// Windows answered from the recent history.
    pub answered: Arc<AtomicU64>,
    /// (point, seq) put while the session had no router.
    pub no_route: HashSet<(usize, u64)>,
    /// Slices published while the session had no router (transport closed or not yet up).
    pub no_route_slices: u64,
    _recent: zenoh::query::Queryable<()>,
}

/// Slices per tick: each point publishes in one of them, spreading a tick's puts.
const SLICES: usize = 10;

impl Fleet {
    /// Declare `points` publishers and the recent-history queryable of run `run_ns`.
    pub(super) fn declare(
        session: &zenoh::Session,
        tag: &str,
        points: usize,
        run_ns: u64,
    ) -> Result<Fleet> {
        let pubs = (0..points)
            .map(|i| {
                session
                    .declare_publisher(format!("rigmon/{tag}-{i}/shaft/nde/health"))
                    .congestion_control(FLEET_CONGESTION)
                    .wait()
                    .map_err(|e| anyhow!("{e}"))
            })
            .collect::<Result<Vec<_>>>()?;
        let published: Arc<Vec<AtomicU64>> = Arc::new((0..points).map(|_| 0.into()).collect());
        let answered = Arc::new(AtomicU64::new(0));
        let (p, a, t) = (published.clone(), answered.clone(), tag.to_string());
        let recent = session
            .declare_queryable(format!("rigmon/{tag}-$*/shaft/nde/{SUFFIX}"))
            .callback(move |q| answer(&q, &t, run_ns, &p, &a))
            .wait()
            .map_err(|e| anyhow!("{e}"))?;
        Ok(Fleet {
            session: session.clone(),
            tag: tag.to_string(),
            run_ns,
            pubs,
            published,
            answered,
            no_route: HashSet::new(),
            no_route_slices: 0,
            _recent: recent,
        })
    }

    /// Wait until the historian's subscription reaches the publishers (at most 20 s).
    pub(super) fn wait_matched(&self) -> Result<()> {
        let t = Instant::now();
        while !self.pubs[0]
            .matching_status()
            .wait()
            .map(|m| m.matching())
            .unwrap_or(false)
        {
            if t.elapsed() > Duration::from_secs(20) {
                bail!("the historian never subscribed to rigmon/**/health");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        Ok(())
    }

    /// Publish windows `first..=last` of every point on the 2-windows/s clock that started
    /// at `t0`; returns how late the publisher fell behind that clock at most (s).
    pub(super) fn publish(&mut self, t0: Instant, first: u64, last: u64) -> Result<f64> {
        let mut late = 0.0f64;
        for seq in first..=last {
            for s in 0..SLICES {
                let due = Duration::from_secs_f64(
                    (seq - 1) as f64 / RATE + s as f64 / (RATE * SLICES as f64),
                );
                match due.checked_sub(t0.elapsed()) {
                    Some(wait) => std::thread::sleep(wait),
                    None => late = late.max((t0.elapsed() - due).as_secs_f64()),
                }
                let routed = self.session.info().routers_zid().wait().next().is_some();
                if !routed {
                    self.no_route_slices += 1;
                }
                for i in (s..self.pubs.len()).step_by(SLICES) {
                    let mut m = window(&self.tag, i, seq, self.run_ns);
                    m.publish_time_ns = now_ns();
                    self.pubs[i]
                        .put(serde_json::to_vec(&m)?)
                        .wait()
                        .map_err(|e| anyhow!("{e}"))?;
                    self.published[i].fetch_max(seq, Ordering::Relaxed);
                    if !routed {
                        self.no_route.insert((i, seq));
                    }
                }
            }
        }
        Ok(late)
    }
}

/// Answer one recent-history query as the point's daemon would: the windows of the asked run
/// and seq range that it has published.
fn answer(
    q: &zenoh::query::Query,
    tag: &str,
    run_ns: u64,
    published: &[AtomicU64],
    answered: &AtomicU64,
) {
    let key = q.key_expr().as_str().to_string();
    let point = key
        .strip_prefix(&format!("rigmon/{tag}-"))
        .and_then(|r| r.strip_suffix(&format!("/shaft/nde/{SUFFIX}")))
        .and_then(|n| n.parse::<usize>().ok());
    let (Some(i), Ok(rq)) = (point, RecentQuery::parse(q.parameters(), now_ns())) else {
        return;
    };
    let Some(high) = published.get(i).map(|p| p.load(Ordering::Relaxed)) else {
        return;
    };
    // the daemon's word on what it holds, after the windows (a query by run and seq)
    let held = rq
        .run_start_ns
        .filter(|_| !rq.seq.is_empty())
        .map(|r| Held {
            run_start_ns: r,
            seqs: (same_run(r, run_ns) && high > 0).then_some((1, high)),
        });
    if rq.run_start_ns.is_none_or(|r| same_run(r, run_ns)) {
        let ranges = if rq.seq.is_empty() {
            vec![(1, high)]
        } else {
            rq.seq
        };
        for seq in ranges.into_iter().flat_map(|(a, b)| a.max(1)..=b.min(high)) {
            let mut m = window(tag, i, seq, run_ns);
            m.publish_time_ns = now_ns();
            let Ok(json) = serde_json::to_vec(&m) else {
                return;
            };
            if q.reply(key.clone(), json).wait().is_err() {
                return;
            }
            answered.fetch_add(1, Ordering::Relaxed);
        }
    }
    if let Some(h) = held {
        h.reply(q);
    }
}
