//! Issue 6: the page streamer. Memory stays within its byte budget under 100 000
//! random page requests; callers never wait for the workers; pages hold what a direct
//! fill of their region gives; a missing page is served from a coarser resident level.

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use surftile::stream::{PageKey, PageStreamer, Region, Surface, View};

/// A cheap surface: h(x, y) = sin(x/7) + y/1000.
struct Ramp;
impl Surface for Ramp {
    fn channels(&self) -> usize {
        1
    }
    fn sample_footprint(&self, x: f64, y: f64, _footprint: f64, out: &mut [f32]) {
        out[0] = ((x / 7.0).sin() + y / 1000.0) as f32;
    }
}

/// A surface whose fills wait at a gate until the test opens it, counting the workers
/// that are inside.
struct Gated {
    open: Mutex<bool>,
    bell: Condvar,
    inside: AtomicUsize,
}
impl Surface for Gated {
    fn channels(&self) -> usize {
        1
    }
    fn sample_footprint(&self, x: f64, y: f64, f: f64, out: &mut [f32]) {
        Ramp.sample_footprint(x, y, f, out)
    }
    fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        self.inside.fetch_add(1, Ordering::SeqCst);
        let mut open = self.open.lock().unwrap();
        while !*open {
            open = self.bell.wait(open).unwrap();
        }
        drop(open);
        Ramp.fill_rows(region, rows, out);
    }
}

fn wait_for(what: &str, mut done: impl FnMut() -> bool) {
    let start = Instant::now();
    while !done() {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "timed out: {what}"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The region a page covers, filled directly.
fn direct(key: PageKey, size: usize) -> Vec<f32> {
    let step = (key.level as f64).exp2();
    let side = size as f64 * step;
    let r = Region::new(key.px as f64 * side, key.py as f64 * side, size, size).with_step(step);
    let mut v = vec![0.0f32; size * size];
    Ramp.fill(&r, &mut v).unwrap();
    v
}

#[test]
fn memory_stays_within_the_budget_under_random_requests() {
    let budget = 64 << 20;
    let size = 256;
    let page_bytes = size * size * 4;
    let s = PageStreamer::new(Arc::new(Ramp), size, 2, budget).unwrap();
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut rand = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    // 100 000 page requests, 8 at a time, each batch replacing the last (so most are
    // cancelled); every 25th batch is left to fill, so that far more pages are filled
    // than the budget holds and the cache evicts.
    for batch in 0..12_500 {
        let keys: Vec<PageKey> = (0..8)
            .map(|_| PageKey {
                level: (rand() % 9) as u32,
                px: (rand() % 2_000_001) as i64 - 1_000_000,
                py: (rand() % 2_000_001) as i64 - 1_000_000,
            })
            .collect();
        s.request_keys(&keys);
        let st = s.stats();
        assert!(st.held_bytes <= budget, "{st:?}");
        if batch % 25 == 0 {
            wait_for("a batch to fill", || s.stats().pending == 0);
        }
    }
    wait_for("the queue to drain", || s.stats().pending == 0);
    let st = s.stats();
    eprintln!("{st:?}");
    assert!(
        st.peak_bytes <= budget,
        "peak {} > budget {budget}",
        st.peak_bytes
    );
    assert!(st.held_bytes <= budget);
    // The cache was used up to its budget, not starved by cancellation.
    assert!(
        st.resident * page_bytes > budget - 4 * page_bytes,
        "only {} pages resident",
        st.resident
    );
    assert!(st.cancelled > 0 && st.filled > 1000, "{st:?}");
}

#[test]
fn callers_never_wait_for_busy_workers() {
    let gated = Arc::new(Gated {
        open: Mutex::new(false),
        bell: Condvar::new(),
        inside: AtomicUsize::new(0),
    });
    let s = PageStreamer::new(gated.clone(), 64, 2, 8 << 20).unwrap();
    let view = View {
        x: -100.0,
        y: 50.0,
        width: 200,
        height: 100,
        scale: 1.0,
    };
    let visible = s.request(&view);
    // Both workers are now stuck inside a fill.
    wait_for("both workers to block", || {
        gated.inside.load(Ordering::SeqCst) == 2
    });
    // The render loop goes on: requests for moving views and page lookups return while
    // every worker is blocked, with nothing resident yet.
    for k in 0..1000 {
        let v = View {
            x: view.x + k as f64,
            ..view
        };
        let keys = s.request(&v);
        assert!(keys.iter().all(|&key| s.best(key).is_none()));
    }
    assert_eq!(gated.inside.load(Ordering::SeqCst), 2);
    s.request(&view);
    *gated.open.lock().unwrap() = true;
    gated.bell.notify_all();
    wait_for("the visible pages", || {
        visible.iter().all(|&k| s.best(k).is_some())
    });
    for &k in &visible {
        let p = s.best(k).unwrap();
        assert_eq!(p.key, k);
        assert_eq!(p.data, direct(k, 64), "{k:?}");
    }
}

#[test]
fn a_missing_page_is_served_from_a_coarser_level() {
    let s = PageStreamer::new(Arc::new(Ramp), 64, 2, 8 << 20).unwrap();
    let coarse = PageKey {
        level: 3,
        px: -2,
        py: 5,
    };
    s.request_keys(&[coarse]);
    wait_for("the coarse page", || s.best(coarse).is_some());
    // Level 1, inside the coarse page: px >> 2 = −2, py >> 2 = 5.
    let fine = PageKey {
        level: 1,
        px: -7,
        py: 22,
    };
    let p = s.best(fine).unwrap();
    assert_eq!(p.key, coarse);
    assert_eq!(p.data, direct(coarse, 64));
    // Outside it, nothing.
    assert!(
        s.best(PageKey {
            level: 1,
            px: 0,
            py: 22
        })
        .is_none()
    );
}

#[test]
fn views_map_to_levels_and_pages() {
    let s = PageStreamer::new(Arc::new(Ramp), 256, 1, 4 << 20).unwrap();
    let v = View {
        x: -10.0,
        y: 300.0,
        width: 800,
        height: 600,
        scale: 16.0,
    };
    assert_eq!(s.level_for(&v), 4);
    assert_eq!(s.level_for(&View { scale: 0.5, ..v }), 0);
    // Level 4 pages cover 4096 px: x from −10 to 12 790, y from 300 to 9 900.
    let keys = s.pages_for(&v, 4, 0);
    let xs: Vec<i64> = keys.iter().filter(|k| k.py == 0).map(|k| k.px).collect();
    assert_eq!(xs, vec![-1, 0, 1, 2, 3]);
    assert_eq!(keys.len(), 5 * 3);
    assert_eq!(s.pages_for(&v, 4, 1).len(), 7 * 5);
    // A budget below a page per worker and one more (3 × 256 KiB).
    assert!(PageStreamer::new(Arc::new(Ramp), 256, 2, 512 << 10).is_err());
    assert!(PageStreamer::new(Arc::new(Ramp), 8, 2, 1 << 20).is_err());
}

/// The viewer's render loop for CPU-only sources (`surftile::view::compose`, what each
/// frame of a streamed source runs) returns while every worker is blocked inside a
/// fill: the frame shows nothing (NaN, drawn grey) yet, pages stay pending, and once the
/// workers are let go the same call fills the frame with the surface's own values.
#[test]
fn the_viewers_frame_returns_while_workers_are_busy() {
    let gated = Arc::new(Gated {
        open: Mutex::new(false),
        bell: Condvar::new(),
        inside: AtomicUsize::new(0),
    });
    // Opens the gate however the test ends, so the streamer's drop can join its workers.
    struct OpenOnDrop(Arc<Gated>);
    impl Drop for OpenOnDrop {
        fn drop(&mut self) {
            *self.0.open.lock().unwrap() = true;
            self.0.bell.notify_all();
        }
    }
    let s = PageStreamer::new(gated.clone(), 64, 2, 8 << 20).unwrap();
    let _gate = OpenOnDrop(gated.clone());
    let region = Region::new(-37.0, 20.0, 96, 80);
    let mut frame = vec![0.0f32; region.len()];
    assert!(!surftile::view::compose(&s, &region, &mut frame));
    wait_for("both workers to block", || {
        gated.inside.load(Ordering::SeqCst) == 2
    });
    // 100 frames while both workers are stuck: each returns, incomplete.
    for k in 0..100 {
        frame.fill(0.0);
        let moved = Region::new(region.x + k as f64, region.y, 96, 80);
        assert!(!surftile::view::compose(&s, &moved, &mut frame));
        assert!(frame.iter().all(|v| v.is_nan()), "frame {k}");
        assert!(s.stats().pending > 0);
    }
    *gated.open.lock().unwrap() = true;
    gated.bell.notify_all();
    wait_for("a complete frame", || {
        surftile::view::compose(&s, &region, &mut frame)
    });
    let mut want = vec![0.0f32; region.len()];
    Ramp.fill(&region, &mut want).unwrap();
    assert_eq!(frame, want);
}
