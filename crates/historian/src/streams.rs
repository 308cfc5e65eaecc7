//! Several COPY streams over the points: `[batch] streams` connections, each a [`Writer`]
//! with its own transaction, and every point always on the same one (a hash of its key), so
//! the transactions touch disjoint rows of `windows`, `minutes`, `point_latest`, `events`
//! and `point_status` and never wait for each other. A batch is split by point, registered
//! and partitioned one stream after the other (the shared asset tree, models and partitions
//! in plain statements, in one order), then its transactions run at once: PostgreSQL works
//! on each in its own backend, and the historian encodes one stream's COPY while the others
//! are in the database. The batch is done when every stream has committed; a stream that
//! fails makes the whole batch be retried, and the rows its siblings committed then come
//! back as duplicates (`ON CONFLICT DO NOTHING`): exactly once, as with one stream.

use super::database::Target;
use super::row::WindowRow;
use super::writer::{Outcome, StatusRow, Writer};
use anyhow::Result;
use std::future::Future;
use std::pin::Pin;
use std::task::Poll;

/// The historian's writing connections; the first one also migrates, reads the positions
/// and does the occasional statements (retention, zone limits).
pub struct Streams {
    writers: Vec<Writer>,
}

/// FNV-1a over the key's parts: stable across runs and processes.
fn fnv(parts: &[&[u8]]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in parts {
        for &b in *p {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// The stream of the point `<machine>/<asset>/<point>` among `n`.
pub fn stream_of_key(key: &str, n: usize) -> usize {
    (fnv(&[key.as_bytes()]) % n.max(1) as u64) as usize
}

fn stream_of_row(r: &WindowRow, n: usize) -> usize {
    let p = &r.point;
    let h = fnv(&[
        p.machine.as_bytes(),
        b"/",
        p.asset.as_bytes(),
        b"/",
        p.point.as_bytes(),
    ]);
    (h % n.max(1) as u64) as usize
}

impl Streams {
    /// Open `n` (at least 1) connections to `target`, each with `synchronous_commit` as
    /// given; the first applies the migrations. Returns the schema version.
    pub async fn open(target: &Target, n: usize, synchronous_commit: bool) -> Result<(Self, i32)> {
        let mut writers = Vec::new();
        let mut version = 0;
        for _ in 0..n.max(1) {
            let (w, v) = Writer::open(target).await?;
            w.set_synchronous_commit(synchronous_commit).await?;
            version = v;
            writers.push(w);
        }
        Ok((Streams { writers }, version))
    }

    /// The first connection (positions, retention, zone limits, row-by-row retries).
    pub fn first(&mut self) -> &mut Writer {
        &mut self.writers[0]
    }

    /// True when any connection is gone.
    pub fn is_closed(&self) -> bool {
        self.writers.iter().any(Writer::is_closed)
    }

    /// Every writer learns the points already in the database.
    pub async fn load_points(&mut self) -> Result<()> {
        for w in &mut self.writers {
            w.load_points().await?;
        }
        Ok(())
    }

    /// Write one batch over the streams (rows reordered by stream, each point's in order).
    pub async fn write(
        &mut self,
        rows: &mut [WindowRow],
        statuses: &[StatusRow],
    ) -> Result<Outcome> {
        let n = self.writers.len();
        if n == 1 {
            return self.writers[0].write(rows, statuses).await;
        }
        rows.sort_by_cached_key(|r| stream_of_row(r, n));
        let mut parts: Vec<&mut [WindowRow]> = Vec::with_capacity(n);
        let mut rest = rows;
        for i in 0..n {
            let len = rest.iter().take_while(|r| stream_of_row(r, n) == i).count();
            let (part, tail) = rest.split_at_mut(len);
            parts.push(part);
            rest = tail;
        }
        let mut sts: Vec<Vec<StatusRow>> = vec![Vec::new(); n];
        for s in statuses {
            sts[stream_of_key(&s.key, n)].push(s.clone());
        }
        let mut out = Outcome::default();
        for (w, part) in self.writers.iter_mut().zip(parts.iter_mut()) {
            w.prepare(part, &mut out.new_points).await?;
        }
        let futures: Vec<Pin<Box<dyn Future<Output = Result<Outcome>> + Send + '_>>> = self
            .writers
            .iter_mut()
            .zip(parts.iter())
            .zip(sts.iter())
            .map(|((w, part), s)| {
                Box::pin(w.write_prepared(part, s)) as Pin<Box<dyn Future<Output = _> + Send>>
            })
            .collect();
        for o in join_all(futures).await {
            let o = o?;
            out.inserted += o.inserted;
            out.duplicates += o.duplicates;
            out.events += o.events;
        }
        Ok(out)
    }
}

/// Poll every future until all are ready; their outputs in order.
async fn join_all<T>(mut futures: Vec<Pin<Box<dyn Future<Output = T> + Send + '_>>>) -> Vec<T> {
    let mut done: Vec<Option<T>> = futures.iter().map(|_| None).collect();
    std::future::poll_fn(|cx| {
        let mut waiting = false;
        for (f, d) in futures.iter_mut().zip(done.iter_mut()) {
            if d.is_none() {
                match f.as_mut().poll(cx) {
                    Poll::Ready(v) => *d = Some(v),
                    Poll::Pending => waiting = true,
                }
            }
        }
        if waiting {
            Poll::Pending
        } else {
            Poll::Ready(())
        }
    })
    .await;
    done.into_iter().flatten().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_point_keeps_its_stream_and_points_spread_over_them() {
        let n = 2;
        let mut count = [0usize; 2];
        for i in 0..1000 {
            let key = format!("rig-{i}/shaft/nde");
            let s = stream_of_key(&key, n);
            assert_eq!(s, stream_of_key(&key, n), "stable");
            count[s] += 1;
        }
        assert!(count.iter().all(|&c| c > 400), "{count:?}");
        assert_eq!(stream_of_key("a/b/c", 1), 0);
    }
}
