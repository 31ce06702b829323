//! The page streamer: fixed-size pages of any [`Surface`], filled by a crossbeam worker
//! pool into an LRU cache with a byte budget, for callers that must never wait (the
//! viewer's render loop, for the CPU-only sources such as RSGF).
//!
//! - A page is keyed by (level, px, py): at level L it holds `size × size` samples with
//!   step 2ᴸ, its first at level-0 pixel (px·size·2ᴸ, py·size·2ᴸ).
//! - [`PageStreamer::request`] names the pages a view needs (plus a prefetch ring
//!   around it). Missing ones are queued for the workers; queued ones that left the view
//!   are cancelled, and a worker skips a cancelled page without filling it.
//! - [`PageStreamer::best`] returns at once: the page if it is resident, else the
//!   resident page of the nearest coarser level that covers it, else nothing.
//! - Memory: the bytes of resident pages plus those of pages being filled never exceed
//!   the budget. A worker reserves its page's bytes (evicting least recently used pages)
//!   before it fills, and the high-water mark is kept for tests.

use std::collections::HashMap;
use std::num::NonZeroUsize;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;

use crossbeam::channel::{Receiver, Sender, unbounded};
use lru::LruCache;

use super::{Region, Surface};
use crate::error::{Error, Result};

/// A page's key: mip level and page column and row at that level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PageKey {
    /// Level L: samples are 2ᴸ level-0 pixels apart.
    pub level: u32,
    /// Page column at this level.
    pub px: i64,
    /// Page row at this level.
    pub py: i64,
}

/// A filled page: `size × size` samples of `channels` values, row-major.
#[derive(Debug)]
pub struct Page {
    /// Its key.
    pub key: PageKey,
    /// Samples per side.
    pub size: usize,
    /// Values per sample.
    pub channels: usize,
    /// The samples.
    pub data: Vec<f32>,
}

/// A view of the plane: the level-0 rectangle `[x, x + width·scale) × [y, y + height·scale)`
/// shown on `width × height` screen pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Left edge, level-0 pixels.
    pub x: f64,
    /// Top edge, level-0 pixels.
    pub y: f64,
    /// Screen width in pixels.
    pub width: usize,
    /// Screen height in pixels.
    pub height: usize,
    /// Level-0 pixels per screen pixel (> 0); 16 is a 16× zoom-out.
    pub scale: f64,
}

/// What the streamer holds now, and the most it ever held.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PageStats {
    /// Pages resident in the cache.
    pub resident: usize,
    /// Bytes of resident pages plus pages being filled.
    pub held_bytes: usize,
    /// The largest `held_bytes` ever reached.
    pub peak_bytes: usize,
    /// Pages queued or being filled.
    pub pending: usize,
    /// Pages filled so far.
    pub filled: u64,
    /// Queued pages dropped because they left the view before a worker took them.
    pub cancelled: u64,
}

struct Job {
    key: PageKey,
    cancel: Arc<AtomicBool>,
}

struct State {
    resident: LruCache<PageKey, Arc<Page>>,
    /// Queued or in-flight pages and their cancellation flags.
    pending: HashMap<PageKey, Arc<AtomicBool>>,
    resident_bytes: usize,
    inflight_bytes: usize,
    stats: PageStats,
}

impl State {
    /// Removes `job`'s pending entry, if it is still its own (a newer request for the
    /// same key, made after this one was cancelled, keeps its entry); true if it was.
    fn release(&mut self, job: &Job) -> bool {
        let ours = self
            .pending
            .get(&job.key)
            .is_some_and(|c| Arc::ptr_eq(c, &job.cancel));
        if ours {
            self.pending.remove(&job.key);
        }
        ours
    }
}

struct Shared {
    surface: Arc<dyn Surface>,
    size: usize,
    page_bytes: usize,
    budget: usize,
    state: Mutex<State>,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        // A worker that panicked mid-fill leaves the state consistent (it only ever
        // changes it under the lock, in a few statements): keep going.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The worker loop: take a job, skip it if cancelled, reserve its bytes, fill it,
    /// make it resident.
    fn work(&self, jobs: Receiver<Job>) {
        while let Ok(job) = jobs.recv() {
            {
                let mut st = self.lock();
                if job.cancel.load(Ordering::Relaxed) {
                    st.stats.cancelled += 1;
                    continue;
                }
                // Reserve: evict least recently used pages until this one fits.
                while st.resident_bytes + st.inflight_bytes + self.page_bytes > self.budget {
                    match st.resident.pop_lru() {
                        Some(_) => st.resident_bytes -= self.page_bytes,
                        None => break,
                    }
                }
                if st.resident_bytes + st.inflight_bytes + self.page_bytes > self.budget {
                    // Every byte is in flight on other workers: give the page up; a
                    // later request asks again.
                    st.release(&job);
                    continue;
                }
                st.inflight_bytes += self.page_bytes;
                let held = st.resident_bytes + st.inflight_bytes;
                st.stats.peak_bytes = st.stats.peak_bytes.max(held);
            }
            let page = self.fill(job.key);
            let mut st = self.lock();
            st.inflight_bytes -= self.page_bytes;
            if st.release(&job) && !job.cancel.load(Ordering::Relaxed) {
                st.resident.put(job.key, Arc::new(page));
                st.resident_bytes += self.page_bytes;
            }
            st.stats.filled += 1;
        }
    }

    fn fill(&self, key: PageKey) -> Page {
        let step = (key.level as f64).exp2();
        let side = self.size as f64 * step;
        let region = Region::new(
            key.px as f64 * side,
            key.py as f64 * side,
            self.size,
            self.size,
        )
        .with_step(step);
        let c = self.surface.channels();
        let mut data = vec![0.0f32; self.size * self.size * c];
        // One thread per page: the pool's workers are the parallelism.
        self.surface.fill_rows(&region, 0..self.size, &mut data);
        Page {
            key,
            size: self.size,
            channels: c,
            data,
        }
    }
}

/// Pages of a surface, filled in the background (see the module documentation).
pub struct PageStreamer {
    shared: Arc<Shared>,
    jobs: Option<Sender<Job>>,
    workers: Vec<JoinHandle<()>>,
    max_level: u32,
}

/// Most mip levels a streamer serves: level 24 samples every 2²⁴ pixels.
pub const MAX_PAGE_LEVEL: u32 = 24;

impl PageStreamer {
    /// A streamer of `surface` in pages of `size × size` samples, on `workers` threads,
    /// holding at most `budget_bytes` of pages. The budget must hold a page per worker
    /// and one more.
    pub fn new(
        surface: Arc<dyn Surface>,
        size: usize,
        workers: usize,
        budget_bytes: usize,
    ) -> Result<PageStreamer> {
        if !(16..=4096).contains(&size) {
            return Err(Error::param("page size", size, "16 to 4096 samples"));
        }
        if !(1..=256).contains(&workers) {
            return Err(Error::param("workers", workers, "1 to 256 threads"));
        }
        let page_bytes = size * size * surface.channels() * std::mem::size_of::<f32>();
        if budget_bytes < page_bytes * (workers + 1) {
            return Err(Error::param(
                "page budget",
                format!("{budget_bytes} bytes"),
                format!(
                    "at least {} bytes (a {size}² page per worker and one more)",
                    page_bytes * (workers + 1)
                ),
            ));
        }
        let capacity = NonZeroUsize::new(budget_bytes / page_bytes + 1).expect("≥ 1");
        let shared = Arc::new(Shared {
            surface,
            size,
            page_bytes,
            budget: budget_bytes,
            state: Mutex::new(State {
                resident: LruCache::new(capacity),
                pending: HashMap::new(),
                resident_bytes: 0,
                inflight_bytes: 0,
                stats: PageStats::default(),
            }),
        });
        let (tx, rx) = unbounded::<Job>();
        let workers = (0..workers)
            .map(|k| {
                let (shared, rx) = (shared.clone(), rx.clone());
                std::thread::Builder::new()
                    .name(format!("surftile-page-{k}"))
                    .spawn(move || shared.work(rx))
                    .map_err(|e| {
                        Error::Limits(format!("could not start a page worker thread: {e}"))
                    })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(PageStreamer {
            shared,
            jobs: Some(tx),
            workers,
            max_level: MAX_PAGE_LEVEL,
        })
    }

    /// Samples per page side.
    pub fn page_size(&self) -> usize {
        self.shared.size
    }

    /// The level a view reads: ⌊log2 scale⌋ (a scale within 10⁻⁹ below a power of two
    /// counts as it), within 0..=24.
    pub fn level_for(&self, view: &View) -> u32 {
        if !(view.scale.is_finite() && view.scale > 1.0) {
            return 0;
        }
        ((view.scale.log2() + 1e-9).floor() as u32).min(self.max_level)
    }

    /// The pages of `level` that cover `view`, grown by `margin` pages on every side,
    /// row by row.
    pub fn pages_for(&self, view: &View, level: u32, margin: i64) -> Vec<PageKey> {
        let side = self.shared.size as f64 * (level as f64).exp2();
        let (w, h) = (
            view.width as f64 * view.scale,
            view.height as f64 * view.scale,
        );
        let range = |a: f64, len: f64| {
            let lo = (a / side).floor() as i64 - margin;
            let hi = ((a + len) / side).ceil() as i64 - 1 + margin;
            lo..=hi.max(lo)
        };
        let (xs, ys) = (range(view.x, w), range(view.y, h));
        ys.flat_map(|py| xs.clone().map(move |px| PageKey { level, px, py }))
            .collect()
    }

    /// Asks for the pages of `view` (and, after them, a prefetch ring of one page around
    /// it): queues those neither resident nor queued, and cancels queued pages that are
    /// no longer wanted. Returns at once with the visible keys.
    pub fn request(&self, view: &View) -> Vec<PageKey> {
        let level = self.level_for(view);
        let visible = self.pages_for(view, level, 0);
        let mut wanted = visible.clone();
        wanted.extend(
            self.pages_for(view, level, 1)
                .into_iter()
                .filter(|k| !visible.contains(k)),
        );
        self.request_keys(&wanted);
        visible
    }

    /// Asks for exactly `keys`, in order (see [`Self::request`]).
    pub fn request_keys(&self, keys: &[PageKey]) {
        let Some(jobs) = &self.jobs else { return };
        let mut st = self.shared.lock();
        let keep: std::collections::HashSet<PageKey> = keys.iter().copied().collect();
        st.pending.retain(|k, cancel| {
            let keep = keep.contains(k);
            if !keep {
                cancel.store(true, Ordering::Relaxed);
            }
            keep
        });
        for &key in keys {
            if st.resident.contains(&key) || st.pending.contains_key(&key) {
                continue;
            }
            let cancel = Arc::new(AtomicBool::new(false));
            st.pending.insert(key, cancel.clone());
            // The receivers live as long as the workers, which live as long as `self`.
            let _ = jobs.send(Job { key, cancel });
        }
        st.stats.pending = st.pending.len();
    }

    /// The best resident page for `key`: itself, or the page of the nearest coarser
    /// level that covers it (and that level). Never waits for a worker.
    pub fn best(&self, key: PageKey) -> Option<Arc<Page>> {
        let mut st = self.shared.lock();
        for up in 0..=(self.max_level.saturating_sub(key.level)) {
            let k = PageKey {
                level: key.level + up,
                px: key.px >> up,
                py: key.py >> up,
            };
            if let Some(p) = st.resident.get(&k) {
                return Some(p.clone());
            }
        }
        None
    }

    /// What the streamer holds now.
    pub fn stats(&self) -> PageStats {
        let st = self.shared.lock();
        PageStats {
            resident: st.resident.len(),
            held_bytes: st.resident_bytes + st.inflight_bytes,
            pending: st.pending.len(),
            ..st.stats
        }
    }

    /// The byte budget.
    pub fn budget_bytes(&self) -> usize {
        self.shared.budget
    }
}

impl Drop for PageStreamer {
    /// Cancels every queued page, closes the queue and joins the workers (each finishes
    /// at most the page it is filling).
    fn drop(&mut self) {
        {
            let mut st = self.shared.lock();
            for cancel in st.pending.values() {
                cancel.store(true, Ordering::Relaxed);
            }
            st.pending.clear();
        }
        self.jobs = None;
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}
