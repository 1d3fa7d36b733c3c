//! A team of threads for the XPBD substep's short passes: helpers that spin between passes.
//!
//! A substep is a dozen passes of 10–100 µs each (the cells' colours, the node passes) with
//! serial stages between them (the display-surface points' contacts, the body contacts). On
//! rayon's pool an idle worker sleeps on a futex within a few tens of microseconds, so every
//! pass after a serial stage paid a wake-up, and on a 2-core virtual machine a wake-up (an
//! inter-processor interrupt through the hypervisor and a context switch) cost about as much
//! as the pass itself: the standard scene ran slower on two threads than on one (2.54 against
//! 2.19 s). rayon has no spin setting, and the lighter pools on crates.io (paralight, chili)
//! wait on condition variables too, so this module keeps its own helpers: after a pass they
//! watch for the next one for [`SPIN`] (at full speed for [`HOT_SPINS`] checks, then giving
//! the core to any other thread between checks: spinning alone made two bakes sharing two
//! cores 50 % slower), and only then sleep on a condition variable.
//!
//! The caller takes part: a pass is `count` tasks claimed one at a time from a shared
//! counter, by the caller and by whichever helpers are awake; the caller returns once every
//! task has run and no helper still reads the pass. A helper asleep when a pass is posted is
//! woken but not waited for. Each task writes what only it writes ([`Parts`]), so the result
//! has the same bits whoever runs which task, on any thread count.
//!
//! Teams are process-wide, one per size, built on first use ([`with_team`]); a team serves one
//! world at a time, and a world that finds its team busy (another world stepping on another
//! thread, as the tests do) runs its passes on its own thread. Nothing is allocated per pass.

use std::cell::Cell;
use std::marker::PhantomData;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicU64, AtomicUsize, Ordering::SeqCst};
use std::sync::{Condvar, Mutex, MutexGuard, OnceLock, TryLockError};
use std::time::{Duration, Instant};

/// How long an idle helper watches for the next pass before it sleeps: longer than the
/// serial stages between a substep's passes (the standard scene's longest, the points'
/// contacts, takes about 40 µs), short enough that a helper of a world that stopped
/// stepping gives its core back at once.
const SPIN: Duration = Duration::from_micros(200);

/// Checks an idle helper makes at full speed before it yields the core between checks.
const HOT_SPINS: u32 = 256;

/// One pass: `count` tasks of `run`, claimed in turn.
struct Pass<'a> {
    run: &'a (dyn Fn(usize) + Sync),
    count: usize,
    next: AtomicUsize,
    done: AtomicUsize,
    panicked: AtomicBool,
}

impl Pass<'_> {
    /// Claim and run tasks until none is left; a panicking task counts as done and marks the
    /// pass (the caller panics once the pass is over).
    fn work(&self) {
        loop {
            let i = self.next.fetch_add(1, SeqCst);
            if i >= self.count {
                return;
            }
            if catch_unwind(AssertUnwindSafe(|| (self.run)(i))).is_err() {
                self.panicked.store(true, SeqCst);
            }
            self.done.fetch_add(1, SeqCst);
        }
    }
}

/// What the caller and its helpers share.
struct Shared {
    /// Number of the pass posted last (helpers run each pass at most once).
    epoch: AtomicU64,
    /// The pass being run, or null between passes.
    pass: AtomicPtr<Pass<'static>>,
    /// Helpers between reading `pass` and letting go of it.
    reading: AtomicUsize,
    /// Helpers asleep on `wake`.
    sleepers: AtomicUsize,
    lock: Mutex<()>,
    wake: Condvar,
}

/// A caller's helpers (see the module docs).
pub(crate) struct Team {
    shared: &'static Shared,
    in_use: Mutex<()>,
}

impl Team {
    /// A team of `helpers` threads besides the caller; `None` if the system refuses a thread.
    fn new(helpers: usize) -> Option<Team> {
        let shared: &'static Shared = Box::leak(Box::new(Shared {
            epoch: AtomicU64::new(0),
            pass: AtomicPtr::new(std::ptr::null_mut()),
            reading: AtomicUsize::new(0),
            sleepers: AtomicUsize::new(0),
            lock: Mutex::new(()),
            wake: Condvar::new(),
        }));
        for i in 0..helpers {
            std::thread::Builder::new()
                .name(format!("springbake-team{}-{i}", helpers + 1))
                .spawn(move || help(shared))
                .ok()?;
        }
        Some(Team {
            shared,
            in_use: Mutex::new(()),
        })
    }

    /// Run `run(i)` for every `i` in `0..count`, on the caller and the awake helpers; returns
    /// when all have run. A task's panic is raised here, after the pass.
    fn run(&self, count: usize, run: &(dyn Fn(usize) + Sync)) {
        let pass = Pass {
            run,
            count,
            next: AtomicUsize::new(0),
            done: AtomicUsize::new(0),
            panicked: AtomicBool::new(false),
        };
        let s = self.shared;
        // SAFETY: helpers reach the pass only through `s.pass`, between raising and lowering
        // `reading`; it is cleared below and `reading` waited out before `pass` goes out of
        // scope, so no helper holds the erased lifetime past this call.
        #[allow(unsafe_code)]
        let erased: *mut Pass<'static> = unsafe {
            std::mem::transmute::<*const Pass<'_>, *const Pass<'static>>(&pass) as *mut _
        };
        s.pass.store(erased, SeqCst);
        s.epoch.fetch_add(1, SeqCst);
        if s.sleepers.load(SeqCst) > 0 {
            let _held = lock(&s.lock);
            s.wake.notify_all();
        }
        pass.work();
        wait_until(|| pass.done.load(SeqCst) >= count);
        s.pass.store(std::ptr::null_mut(), SeqCst);
        wait_until(|| s.reading.load(SeqCst) == 0);
        if pass.panicked.load(SeqCst) {
            resume_unwind(Box::new("a solver task panicked"));
        }
    }
}

/// A helper's life: watch for a pass, spinning for [`SPIN`] and then asleep, and work on it.
fn help(s: &'static Shared) {
    let mut seen = s.epoch.load(SeqCst);
    loop {
        let started = Instant::now();
        let mut spins = 0u32;
        while s.epoch.load(SeqCst) == seen {
            // A few hundred checks at full speed, then each check gives the core to any
            // other thread that wants it (another bake on the same cores), then sleep.
            if spins < HOT_SPINS {
                std::hint::spin_loop();
            } else {
                std::thread::yield_now();
            }
            spins = spins.wrapping_add(1);
            if spins.is_multiple_of(16) && started.elapsed() > SPIN {
                let mut held = lock(&s.lock);
                s.sleepers.fetch_add(1, SeqCst);
                while s.epoch.load(SeqCst) == seen {
                    held = s.wake.wait(held).unwrap_or_else(|e| e.into_inner());
                }
                s.sleepers.fetch_sub(1, SeqCst);
            }
        }
        seen = s.epoch.load(SeqCst);
        s.reading.fetch_add(1, SeqCst);
        let pass = s.pass.load(SeqCst);
        // SAFETY: a non-null `pass` is the caller's, alive until `reading` falls to zero
        // (see `Team::run`).
        #[allow(unsafe_code)]
        if let Some(pass) = unsafe { pass.as_ref() } {
            pass.work();
        }
        s.reading.fetch_sub(1, SeqCst);
    }
}

/// Spin until `ready`, yielding the core after the first few thousand checks.
fn wait_until(ready: impl Fn() -> bool) {
    let mut spins = 0u32;
    while !ready() {
        if spins < 4096 {
            std::hint::spin_loop();
            spins += 1;
        } else {
            std::thread::yield_now();
        }
    }
}

fn lock(m: &Mutex<()>) -> MutexGuard<'_, ()> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

thread_local! {
    /// The team this thread's passes run on ([`with_team`]), if any.
    static CURRENT: Cell<Option<&'static Team>> = const { Cell::new(None) };
}

/// Run `f` with a team of `threads` (the caller and `threads − 1` helpers) for its passes
/// ([`for_each`]), when `threads > 1` and the team is free; otherwise `f`'s passes run on the
/// calling thread. The same result either way.
pub(crate) fn with_team<R>(threads: usize, f: impl FnOnce() -> R) -> R {
    if threads < 2 || CURRENT.with(Cell::get).is_some() {
        return f();
    }
    let Some(team) = team_of(threads) else {
        return f();
    };
    let _using = match team.in_use.try_lock() {
        Ok(held) => held,
        // A pass that panicked poisons nothing the team keeps: every pass starts afresh.
        Err(TryLockError::Poisoned(held)) => held.into_inner(),
        Err(TryLockError::WouldBlock) => return f(),
    };
    struct Restore;
    impl Drop for Restore {
        fn drop(&mut self) {
            CURRENT.with(|c| c.set(None));
        }
    }
    CURRENT.with(|c| c.set(Some(team)));
    let _restore = Restore;
    f()
}

/// Whether this thread runs inside [`with_team`] with a team of helpers (so [`for_each`]
/// shares its passes).
pub(crate) fn active() -> bool {
    CURRENT.with(Cell::get).is_some()
}

/// The process's team of `threads` threads, built on first use and kept.
fn team_of(threads: usize) -> Option<&'static Team> {
    use std::collections::BTreeMap;
    static TEAMS: OnceLock<Mutex<BTreeMap<usize, Option<&'static Team>>>> = OnceLock::new();
    let teams = TEAMS.get_or_init(|| Mutex::new(BTreeMap::new()));
    let mut teams = teams.lock().unwrap_or_else(|e| e.into_inner());
    *teams
        .entry(threads)
        .or_insert_with(|| Team::new(threads - 1).map(|t| &*Box::leak(Box::new(t))))
}

/// Run `task(i, parts.part(i))` for every chunk `i` of `parts`, on this thread's team if it
/// has one ([`with_team`]), else in order here.
pub(crate) fn for_each<P: Parts>(parts: P, task: impl Fn(usize, P::Part) + Sync) {
    let count = parts.count();
    let run = |i: usize| {
        // SAFETY: the team runs each index once, so the parts handed out are disjoint.
        #[allow(unsafe_code)]
        let part = unsafe { parts.part(i) };
        task(i, part)
    };
    match CURRENT.with(Cell::get) {
        Some(team) if count > 1 => {
            // A pass started inside a task runs on that task's thread.
            struct Restore(&'static Team);
            impl Drop for Restore {
                fn drop(&mut self) {
                    CURRENT.with(|c| c.set(Some(self.0)));
                }
            }
            CURRENT.with(|c| c.set(None));
            let _restore = Restore(team);
            team.run(count, &run)
        }
        _ => (0..count).for_each(run),
    }
}

/// The sum over the indices in `range`, cut into fixed chunks of `chunk` indices run on the
/// team: each chunk starts from `zero` and `add`s its indices in order, then the chunks' sums
/// are `combine`d in chunk order from `zero`. The chunks do not depend on the thread count, so
/// neither do the bits. `partials` is the caller's scratch (kept so a step allocates nothing).
pub(crate) fn chunked_sum<T: Copy + Send + Sync>(
    range: std::ops::Range<usize>,
    chunk: usize,
    zero: T,
    partials: &mut Vec<T>,
    add: impl Fn(&mut T, usize) + Sync,
    combine: impl Fn(T, T) -> T,
) -> T {
    let chunk = chunk.max(1);
    partials.clear();
    partials.resize(range.len().div_ceil(chunk), zero);
    for_each(Chunks::new(partials, 1), |c, out: &mut [T]| {
        let start = range.start + c * chunk;
        let mut sum = zero;
        for i in start..(start + chunk).min(range.end) {
            add(&mut sum, i);
        }
        out[0] = sum;
    });
    partials.iter().fold(zero, |a, &b| combine(a, b))
}

/// Slices cut into numbered chunks for [`for_each`]: chunk `i` of each.
///
/// # Safety
/// `part(i)` hands out the `i`-th chunks of mutable slices through `&self`: a caller must
/// ask for each `i` at most once while the parts are alive.
#[allow(unsafe_code)]
pub(crate) unsafe trait Parts: Sync {
    type Part;
    /// How many chunks there are (for a tuple, the first's count; the others must have at
    /// least as many).
    fn count(&self) -> usize;
    /// Chunk `i`.
    ///
    /// # Safety
    /// At most once per `i` (see the trait).
    unsafe fn part(&self, i: usize) -> Self::Part;
}

/// A mutable slice in chunks of `len` (the last may be shorter).
pub(crate) struct Chunks<'a, T> {
    ptr: *mut T,
    total: usize,
    len: usize,
    _slice: PhantomData<&'a mut [T]>,
}

impl<'a, T: Send> Chunks<'a, T> {
    pub(crate) fn new(slice: &'a mut [T], len: usize) -> Self {
        Chunks {
            ptr: slice.as_mut_ptr(),
            total: slice.len(),
            len: len.max(1),
            _slice: PhantomData,
        }
    }
}

// SAFETY: `Chunks` is a `&mut [T]` handed out in disjoint pieces (see `Parts`).
#[allow(unsafe_code)]
unsafe impl<T: Send> Sync for Chunks<'_, T> {}
// SAFETY: as above.
#[allow(unsafe_code)]
unsafe impl<T: Send> Send for Chunks<'_, T> {}

// SAFETY: chunk `i` is `[i·len, min((i+1)·len, total))`: disjoint for distinct `i`.
#[allow(unsafe_code)]
unsafe impl<'a, T: Send> Parts for Chunks<'a, T> {
    type Part = &'a mut [T];
    fn count(&self) -> usize {
        self.total.div_ceil(self.len)
    }
    unsafe fn part(&self, i: usize) -> &'a mut [T] {
        let start = (i * self.len).min(self.total);
        let end = (start + self.len).min(self.total);
        // SAFETY: in bounds, and disjoint from every other chunk handed out (trait contract).
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(start), end - start) }
    }
}

/// `n` numbered tasks with no slice of their own.
pub(crate) struct Tasks(pub usize);

// SAFETY: hands out nothing.
#[allow(unsafe_code)]
unsafe impl Parts for Tasks {
    type Part = ();
    fn count(&self) -> usize {
        self.0
    }
    unsafe fn part(&self, _: usize) {}
}

/// A slice that tasks read and write at indices no two tasks of a pass share (a colour's
/// cells' nodes): scattered access, where [`Chunks`] hands out runs.
pub(crate) struct Disjoint<'a, T> {
    ptr: *mut T,
    len: usize,
    _slice: PhantomData<&'a mut [T]>,
}

impl<'a, T: Copy + Send> Disjoint<'a, T> {
    pub(crate) fn new(slice: &'a mut [T]) -> Self {
        Disjoint {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
            _slice: PhantomData,
        }
    }

    /// The element at `i` (panics out of bounds).
    ///
    /// # Safety
    /// No other task of the pass touches index `i`.
    #[allow(unsafe_code)]
    pub(crate) unsafe fn get(&self, i: usize) -> T {
        assert!(i < self.len, "index {i} out of {}", self.len);
        // SAFETY: in bounds; no other thread writes `i` (the caller's contract), and the slice
        // is borrowed mutably for `'a`, so nothing else touches it meanwhile.
        unsafe { self.ptr.add(i).read() }
    }

    /// How many elements there are.
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// Where the elements start, for a caller that reads and writes them with wider loads
    /// and stores (under the contracts of [`Self::get_unchecked`] and [`Self::set_unchecked`]).
    pub(crate) fn as_ptr(&self) -> *mut T {
        self.ptr
    }

    /// The element at `i`, which the caller has checked is in bounds.
    ///
    /// # Safety
    /// `i < self.len()`, and no other task of the pass touches index `i`.
    #[allow(unsafe_code)]
    pub(crate) unsafe fn get_unchecked(&self, i: usize) -> T {
        debug_assert!(i < self.len);
        // SAFETY: the caller's; as for `get` otherwise.
        unsafe { self.ptr.add(i).read() }
    }

    /// Write `value` at `i`, which the caller has checked is in bounds.
    ///
    /// # Safety
    /// `i < self.len()`, and no other task of the pass touches index `i`.
    #[allow(unsafe_code)]
    pub(crate) unsafe fn set_unchecked(&self, i: usize, value: T) {
        debug_assert!(i < self.len);
        // SAFETY: the caller's; as for `get` otherwise.
        unsafe { self.ptr.add(i).write(value) }
    }

    /// Write `value` at `i` (panics out of bounds).
    ///
    /// # Safety
    /// No other task of the pass touches index `i`.
    #[allow(unsafe_code)]
    pub(crate) unsafe fn set(&self, i: usize, value: T) {
        assert!(i < self.len, "index {i} out of {}", self.len);
        // SAFETY: as for `get`.
        unsafe { self.ptr.add(i).write(value) }
    }
}

// SAFETY: `Disjoint` is a `&mut [T]` whose tasks touch disjoint indices (see `get`, `set`).
#[allow(unsafe_code)]
unsafe impl<T: Send> Sync for Disjoint<'_, T> {}

macro_rules! tuple_parts {
    ($($p:ident $i:tt),+) => {
        // SAFETY: each member hands out disjoint chunks, so the tuple does.
        #[allow(unsafe_code)]
        unsafe impl<$($p: Parts),+> Parts for ($($p,)+) {
            type Part = ($($p::Part,)+);
            fn count(&self) -> usize {
                self.0.count()
            }
            unsafe fn part(&self, i: usize) -> Self::Part {
                // SAFETY: forwarded contract.
                unsafe { ($(self.$i.part(i),)+) }
            }
        }
    };
}
tuple_parts!(A 0, B 1);
tuple_parts!(A 0, B 1, C 2);
tuple_parts!(A 0, B 1, C 2, D 3);
tuple_parts!(A 0, B 1, C 2, D 3, E 4);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_chunk_runs_once_on_a_team_and_alone() {
        for threads in [1, 2, 3] {
            let mut a = vec![0u64; 10_001];
            let mut b = vec![0u64; 10_001usize.div_ceil(100)];
            with_team(threads, || {
                for round in 0..200u64 {
                    for_each(
                        (Chunks::new(&mut a, 100), Chunks::new(&mut b, 1)),
                        |i, (a, b)| {
                            for (k, x) in a.iter_mut().enumerate() {
                                *x += (i * 100 + k) as u64 + round;
                            }
                            b[0] += 1;
                        },
                    );
                }
            });
            for (k, &x) in a.iter().enumerate() {
                assert_eq!(
                    x,
                    200 * k as u64 + 199 * 200 / 2,
                    "threads {threads}, item {k}"
                );
            }
            assert!(b.iter().all(|&n| n == 200), "threads {threads}");
        }
    }

    #[test]
    fn a_panicking_task_panics_the_caller_after_the_pass() {
        let team = Team::new(1).expect("a helper thread");
        let done = AtomicUsize::new(0);
        let caught = catch_unwind(AssertUnwindSafe(|| {
            team.run(64, &|i| {
                done.fetch_add(1, SeqCst);
                assert_ne!(i, 7, "task 7 fails");
            })
        }));
        assert!(caught.is_err());
        assert_eq!(
            done.load(SeqCst),
            64,
            "every task ran before the panic was raised"
        );
        // The team is usable afterwards.
        let ran = AtomicUsize::new(0);
        team.run(64, &|_| {
            ran.fetch_add(1, SeqCst);
        });
        assert_eq!(ran.load(SeqCst), 64);
    }
}
