//! Parallel gathers in fixed chunks: every pass of the crate writes each output item from one
//! task, over chunks whose bounds do not depend on the number of threads, so results are bitwise
//! the same whatever the thread count. Also the allocation hints that make a large buffer's first
//! touch cheap (fallible, through [`crate::memory`]), [`Disjoint`] for the passes whose items
//! are not chunks of their output (each item still written by one task), and [`in_pool`].
//! Ground floor: imports only `error` and `memory`.

use std::mem::MaybeUninit;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::memory;

/// Items per parallel task in the gathers: large enough to amortise scheduling (a task of a
/// pass is tens of thousands of instructions), small enough that a level of a few thousand faces
/// makes tasks for both threads and the tasks of a pass end together. Measured 2026-12-04
/// (interleaved wall times of the callgrind driver's cached averaging 4 on the 3,840-quad sphere,
/// two threads, medians of 5-9 rounds at load 1.3-1.4): 4,096 -> 1,024 items made levels 2 / 3 /
/// 4 14 % / 6 % / 5 % faster (one thread: within the noise, +1.3 % instructions); 512 was no
/// better than 1,024.
pub(crate) const CHUNK: usize = 1 << 10;

/// CSR offsets (length `n + 1`) of items with `count(item)` entries each: counts and the
/// prefix sum run in fixed chunks in parallel (integer sums, so the order does not matter).
pub(crate) fn prefix_offsets(n: usize, count: impl Fn(usize) -> u32 + Sync) -> Result<Vec<u32>> {
    let mut offsets = zeroed_hinted::<u32>(n + 1)?;
    offsets[1..]
        .par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(chunk, out)| {
            let mut sum = 0u32;
            for (i, o) in out.iter_mut().enumerate() {
                sum += count(chunk * CHUNK + i);
                *o = sum;
            }
        });
    // Carry each chunk's total into the following chunks.
    let chunks = n.div_ceil(CHUNK);
    let mut carry = Vec::with_capacity(chunks);
    let mut total = 0u32;
    for chunk in 0..chunks {
        carry.push(total);
        total += offsets[((chunk + 1) * CHUNK).min(n)];
    }
    offsets[1..]
        .par_chunks_mut(CHUNK)
        .zip(carry)
        .for_each(|(out, add)| {
            if add != 0 {
                for o in out {
                    *o += add;
                }
            }
        });
    Ok(offsets)
}

/// Allocations from this size on are worth the transparent-huge-page hint.
const HUGE_HINT_BYTES: usize = 4 << 20;

/// An empty vector with room for `n` items, or [`Error::OutOfMemory`]; a large one is advised
/// to use transparent huge pages, which makes its first touch (the page faults) several times
/// cheaper on Linux.
pub(crate) fn with_capacity_hinted<T>(n: usize) -> Result<Vec<T>> {
    let v = memory::with_capacity(n)?;
    advise_huge_pages(v.as_ptr() as usize, v.capacity() * std::mem::size_of::<T>());
    Ok(v)
}

/// `out[i] = f(i)` for `i < n`, in parallel chunks, into a hinted allocation.
pub(crate) fn gather_hinted<V: Send>(
    n: usize,
    f: impl Fn(usize) -> V + Sync + Send,
) -> Result<Vec<V>> {
    let mut v = with_capacity_hinted(n)?;
    fill_spare(&mut v, n, f);
    Ok(v)
}

/// [`gather_hinted`] in tasks of `grain` items rather than [`CHUNK`]: for items of thousands of
/// instructions each (the adaptive decisions' sibling blocks), of which a level has too few for
/// [`CHUNK`] to make more than one or two tasks. Each item is still written by one task, so the
/// result does not depend on the grain or the threads.
pub(crate) fn gather_grain<V: Send>(
    n: usize,
    grain: usize,
    f: impl Fn(usize) -> V + Sync + Send,
) -> Result<Vec<V>> {
    let mut v = with_capacity_hinted(n)?;
    fill_grain(&mut v.spare_capacity_mut()[..n], grain, f);
    // SAFETY: `fill_grain` initialised the first `n` items (a panic would have unwound past here).
    unsafe { v.set_len(n) };
    Ok(v)
}

/// `out[i] = source[index[i]]` for every `i`, in parallel chunks, into a hinted allocation:
/// the gathers of rows by a table (values at corners from values at vertices). The index is
/// walked in step with the output (one bounds check per item, on `source`), about a third of
/// the instructions of [`gather_hinted`] with a closure that reads both.
pub(crate) fn gather_indexed<V: Copy + Send + Sync>(source: &[V], index: &[u32]) -> Result<Vec<V>> {
    let n = index.len();
    let mut v = with_capacity_hinted(n)?;
    (v.spare_capacity_mut()[..n].par_chunks_mut(CHUNK))
        .zip(index.par_chunks(CHUNK))
        .for_each(|(items, index)| {
            // The slice in registers: read through the closure's captures, its pointer and
            // length were loaded again for every item (the writes might have changed them).
            let source: &[V] = source;
            // The chunk's indices checked at once by their maximum (which vectorises; an index
            // past the source panics, as indexing would), then read unchecked.
            let largest = index.iter().copied().max().unwrap_or(0);
            assert!(
                index.is_empty() || (largest as usize) < source.len(),
                "a gather index past the source"
            );
            for (item, &i) in items.iter_mut().zip(index) {
                // SAFETY: every index of the chunk is within `source` (checked above).
                item.write(unsafe { *source.get_unchecked(i as usize) });
            }
        });
    // SAFETY: the loop initialised the first `n` items (a panic would have unwound past here).
    unsafe { v.set_len(n) };
    Ok(v)
}

/// `n` zeros (or defaults) in a hinted allocation, written in parallel.
pub(crate) fn zeroed_hinted<T: Default + Copy + Send + Sync>(n: usize) -> Result<Vec<T>> {
    let mut v = with_capacity_hinted(n)?;
    (0..n)
        .into_par_iter()
        .with_min_len(4 * CHUNK)
        .map(|_| T::default())
        .collect_into_vec(&mut v);
    Ok(v)
}

/// [`with_capacity_hinted`] for the gathers that fill a buffer they are given
/// ([`gather_into`], [`gather_sections`]) and the scratch buffers of a run, where a result
/// cannot be returned; it aborts, as `Vec::with_capacity` does, if the allocation fails. No
/// request reaches it with a buffer to allocate: every run of steps gets its level-sized
/// buffers from a [`crate::step::Scratch`] provisioned fallibly first (`evaluate::run` for the
/// plans and the limits, `LevelData::with_scratch_for` for the adaptive partial levels and the
/// analysis), and a step takes at most the four buffers provisioned (a windowed step), each
/// with room for the largest level; the gathers then find room in the buffer they are given
/// (`Scratch` counts the buffers it had to allocate, and a test of `evaluate` holds every
/// scheme to none).
pub(crate) fn hinted_or_abort<T>(n: usize) -> Vec<T> {
    let v = Vec::with_capacity(n);
    advise_huge_pages(v.as_ptr() as usize, v.capacity() * std::mem::size_of::<T>());
    v
}

#[cfg(target_os = "linux")]
fn advise_huge_pages(start: usize, bytes: usize) {
    const HUGE: usize = 2 << 20;
    if bytes < HUGE_HINT_BYTES {
        return;
    }
    let first = (start + HUGE - 1) & !(HUGE - 1);
    let end = (start + bytes) & !(HUGE - 1);
    if end > first {
        // SAFETY: the range lies inside an allocation we own, and MADV_HUGEPAGE is a hint that
        // changes neither its contents nor its mapping; a failure is harmless and ignored.
        unsafe {
            libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge_pages(_start: usize, _bytes: usize) {}

/// Fills a CSR table in parallel: `fill(item, slice)` writes the entries of `item`, whose slice
/// is `offsets[item]..offsets[item + 1]`. Items are split into fixed chunks, so the result does
/// not depend on the thread count.
pub(crate) fn fill_csr<T: Send>(
    offsets: &[u32],
    data: &mut [T],
    fill: impl Fn(usize, &mut [T]) + Sync,
) {
    csr_chunks(offsets, data)
        .into_par_iter()
        .for_each(|(start, end, piece)| {
            let base = offsets[start] as usize;
            for item in start..end {
                let range = offsets[item] as usize - base..offsets[item + 1] as usize - base;
                fill(item, &mut piece[range]);
            }
        });
}

/// The entries `data` of a CSR table with `offsets` in fixed chunks of [`CHUNK`] items (bounds
/// that do not depend on the thread count): per chunk its first item, its end and its entries.
pub(crate) fn csr_chunks<'a, T>(
    offsets: &[u32],
    data: &'a mut [T],
) -> Vec<(usize, usize, &'a mut [T])> {
    let items = offsets.len() - 1;
    let mut pieces = Vec::with_capacity(items / CHUNK + 1);
    let mut rest = data;
    let mut start = 0;
    while start < items {
        let end = (start + CHUNK).min(items);
        let (piece, tail) = rest.split_at_mut((offsets[end] - offsets[start]) as usize);
        pieces.push((start, end, piece));
        rest = tail;
        start = end;
    }
    pieces
}

/// Fills `out`, rows of `row` values, with `fill(i, row_i)` in parallel chunks of rows (each
/// row written by one task, whatever the number of threads).
pub(crate) fn fill_rows<T: Send>(out: &mut [T], row: usize, fill: impl Fn(usize, &mut [T]) + Sync) {
    if row == 0 {
        return;
    }
    out.par_chunks_mut(row * CHUNK)
        .enumerate()
        .for_each(|(chunk, rows)| {
            for (i, values) in rows.chunks_exact_mut(row).enumerate() {
                fill(chunk * CHUNK + i, values);
            }
        });
}

/// `out[i] = f(i)` for `i < n`, in parallel chunks, reusing the allocation of `out`. It keeps
/// rayon's collect rather than [`fill_spare`]: with `fill_spare` LLVM stopped inlining the
/// closure of the pass that used it most (the averaging step's faces, which now walk their table
/// with [`fill_zip`]: cached averaging 4 had +3.8 % instructions under callgrind).
pub(crate) fn gather_into<V: Send, F: Fn(usize) -> V + Sync + Send>(
    out: &mut Vec<V>,
    n: usize,
    f: F,
) {
    if out.capacity() < n {
        *out = hinted_or_abort(n);
    }
    (0..n)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(f)
        .collect_into_vec(out);
}

/// `out` (empty, with room for `n` items) becomes `f(0), ..., f(n - 1)`, written by [`fill`]:
/// a plain loop per chunk (rayon's `collect_into_vec` goes through its generic per-item folder,
/// about twice the instructions of a small gather).
fn fill_spare<V: Send>(out: &mut Vec<V>, n: usize, f: impl Fn(usize) -> V + Sync + Send) {
    debug_assert!(out.is_empty() && out.capacity() >= n);
    fill(&mut out.spare_capacity_mut()[..n], f);
    // SAFETY: `fill` initialised the first `n` items (a panic would have unwound past here).
    unsafe { out.set_len(n) };
}

/// As [`gather_into`] for data on the vertices of a child level, whose three sections (old
/// vertices, edge points, face points, of the given sizes) each get their own function.
pub(crate) fn gather_sections<V: Send>(
    out: &mut Vec<V>,
    sizes: [usize; 3],
    old: impl Fn(usize) -> V + Sync + Send,
    edge: impl Fn(usize) -> V + Sync + Send,
    face: impl Fn(usize) -> V + Sync + Send,
) {
    let n = sizes.iter().sum();
    if out.capacity() < n {
        *out = hinted_or_abort(n);
    }
    let section = |len: usize| (0..len).into_par_iter().with_min_len(CHUNK);
    section(sizes[0])
        .map(old)
        .chain(section(sizes[1]).map(edge))
        .chain(section(sizes[2]).map(face))
        .collect_into_vec(out);
}

/// `out[i] = f(i, &rows[i])` (initialising every item) for a table of `rows` walked in step with
/// the output, in parallel chunks of [`CHUNK`] items as [`fill`]: the passes whose every item
/// reads one row of a table (a face's corners, an edge's corners) pay no index arithmetic or
/// bounds check for it.
pub(crate) fn fill_zip<R: Sync, V: Send>(
    out: &mut [MaybeUninit<V>],
    rows: &[R],
    f: impl Fn(usize, &R) -> V + Sync + Send,
) {
    assert_eq!(out.len(), rows.len(), "one row per item");
    out.par_chunks_mut(CHUNK)
        .zip(rows.par_chunks(CHUNK))
        .enumerate()
        .for_each(|(chunk, (items, rows))| {
            let start = chunk * CHUNK;
            for (i, (item, row)) in items.iter_mut().zip(rows).enumerate() {
                item.write(f(start + i, row));
            }
        });
}

/// `out` becomes `f(i, &rows[i])` for every row ([`fill_zip`]), reusing its allocation when it
/// has room.
pub(crate) fn gather_zip<R: Sync, V: Send>(
    out: &mut Vec<V>,
    rows: &[R],
    f: impl Fn(usize, &R) -> V + Sync + Send,
) {
    let n = rows.len();
    out.clear();
    if out.capacity() < n {
        *out = hinted_or_abort(n);
    }
    fill_zip(&mut out.spare_capacity_mut()[..n], rows, f);
    // SAFETY: `fill_zip` initialised the first `n` items (a panic would have unwound past here).
    unsafe { out.set_len(n) };
}

/// `out[i] = f(i)` (initialising every item), in parallel chunks of [`CHUNK`] items, each
/// item written by one task, so the result does not depend on the number of threads.
pub(crate) fn fill<V: Send, F: Fn(usize) -> V + Sync + Send>(out: &mut [MaybeUninit<V>], f: F) {
    fill_grain(out, CHUNK, f)
}

/// [`fill`] in chunks of `grain` items.
#[inline(always)]
fn fill_grain<V: Send, F: Fn(usize) -> V + Sync + Send>(
    out: &mut [MaybeUninit<V>],
    grain: usize,
    f: F,
) {
    out.par_chunks_mut(grain)
        .enumerate()
        .for_each(|(chunk, items)| {
            let start = chunk * grain;
            for (i, item) in items.iter_mut().enumerate() {
                item.write(f(start + i));
            }
        });
}

/// `out[G * at[i] + k] = value(at[i])[k]` for every `i` (the groups named by `at`, the others
/// untouched), in parallel chunks of [`CHUNK`] names, so the result does not depend on the
/// number of threads. `at` must be strictly increasing and in range: checked before anything
/// is written (a repeated name would be two threads writing one item), an
/// [`Error::Internal`] otherwise, since the lists come from the crate, never from the user.
pub(crate) fn scatter_uninit<V: Send, const G: usize>(
    out: &mut [MaybeUninit<V>],
    at: &[u32],
    value: impl Fn(usize) -> [V; G] + Sync + Send,
) -> Result<()> {
    if !at.windows(2).all(|w| w[0] < w[1]) {
        return Err(Error::Internal(
            "scatter: names not strictly increasing".into(),
        ));
    }
    if at
        .last()
        .is_some_and(|&last| G * (last as usize + 1) > out.len())
    {
        return Err(Error::Internal("scatter: name out of range".into()));
    }
    struct Out<V>(*mut MaybeUninit<V>);
    // SAFETY: the tasks write disjoint groups (the names are distinct) and read nothing.
    unsafe impl<V: Send> Sync for Out<V> {}
    let target = Out(out.as_mut_ptr());
    at.par_chunks(SCATTER_CHUNK).for_each(|names| {
        let target = &target;
        for &name in names {
            let group = value(name as usize);
            for (k, v) in group.into_iter().enumerate() {
                // SAFETY: in range (checked above) and written by this task only.
                unsafe {
                    target
                        .0
                        .add(G * name as usize + k)
                        .write(MaybeUninit::new(v))
                };
            }
        }
    });
    Ok(())
}

/// Names per task of [`scatter_uninit`]: its lists (a step's zone around the irregular
/// vertices and curves) are short next to a level (1,080-3,632 names a pass for degree 9 at
/// level 2 on the 3,840-quad cage), which chunks of [`CHUNK`] split into two to four tasks.
const SCATTER_CHUNK: usize = CHUNK / 4;

/// A slice that parallel tasks write at distinct indices, each index by one task: the writes
/// of a pass whose items are not in chunks of the output (the limit tiles' vertices). Only
/// writes; nothing is read back through it.
pub(crate) struct Disjoint<'a, V> {
    out: *mut MaybeUninit<V>,
    len: usize,
    _out: std::marker::PhantomData<&'a mut [MaybeUninit<V>]>,
}

// SAFETY: it only moves values of `V` (which is `Send`) into distinct items, as `&mut` chunks
// handed to tasks would.
unsafe impl<V: Send> Sync for Disjoint<'_, V> {}

impl<'a, V> Disjoint<'a, V> {
    /// Writes into `out`, borrowed for as long as the writer lives.
    pub(crate) fn new(out: &'a mut [MaybeUninit<V>]) -> Self {
        Disjoint {
            out: out.as_mut_ptr(),
            len: out.len(),
            _out: std::marker::PhantomData,
        }
    }

    /// The number of items.
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// `out[i] = v`, for a caller that has checked its indices against [`Disjoint::len`] (once,
    /// not per write: the limit tiles check their vertices when they start).
    ///
    /// # Safety
    /// `i` is less than [`Disjoint::len`], and no other call, on any thread, writes index `i`
    /// while the writer lives.
    #[inline(always)]
    pub(crate) unsafe fn write(&self, i: usize, v: V) {
        // SAFETY: in range, and this call alone writes item `i` (the caller's contract).
        unsafe { self.out.add(i).write(MaybeUninit::new(v)) };
    }

    /// The address of item `i`, for a caller that writes it in place (a masked vector store).
    ///
    /// # Safety
    /// As [`Disjoint::write`]: `i` is less than [`Disjoint::len`], and only this caller writes
    /// item `i`, through the address alone, while the writer lives.
    #[inline(always)]
    pub(crate) unsafe fn slot(&self, i: usize) -> *mut V {
        // SAFETY: in range (the caller's contract); `MaybeUninit<V>` has the layout of `V`.
        unsafe { self.out.add(i).cast() }
    }
}

/// [`scatter_uninit`] into initialised items (which stay initialised: only values are written).
pub(crate) fn scatter<V: Send, const G: usize>(
    out: &mut [V],
    at: &[u32],
    value: impl Fn(usize) -> [V; G] + Sync + Send,
) -> Result<()> {
    // SAFETY: `scatter_uninit` writes only values, so every item of `out` stays initialised.
    let out = unsafe { as_uninit(out) };
    scatter_uninit(out, at, value)
}

/// `items` as slots to write, for the writers of uninitialised memory.
///
/// # Safety
/// Only values may be written into the slots (never `MaybeUninit::uninit()`), so that every
/// item stays initialised.
pub(crate) unsafe fn as_uninit<V>(items: &mut [V]) -> &mut [MaybeUninit<V>] {
    // SAFETY: `MaybeUninit<V>` has the layout of `V`; the caller writes only values.
    unsafe { &mut *(items as *mut [V] as *mut [MaybeUninit<V>]) }
}

/// Runs `work` on a thread of rayon's pool. A run of many short parallel loops started from
/// outside the pool hands every loop to the pool and waits for it (two thread wake-ups per
/// loop); started from inside, the loops split and join there.
pub(crate) fn in_pool<R: Send>(work: impl FnOnce() -> R + Send) -> R {
    if rayon::current_thread_index().is_some() {
        work()
    } else {
        rayon::scope(|_| work())
    }
}

#[cfg(test)]
mod tests {
    use super::{gather_indexed, CHUNK};

    /// Every index of several chunks is read (each chunk's indices are checked once, then read
    /// unchecked).
    #[test]
    fn gather_indexed_reads_every_index() {
        let source: Vec<[f32; 3]> = (0..100)
            .map(|i| [i as f32, 2.0 * i as f32, -(i as f32)])
            .collect();
        let index: Vec<u32> = (0..3 * CHUNK as u32 + 7).map(|k| (k * 37) % 100).collect();
        let out = gather_indexed(&source, &index).unwrap();
        assert_eq!(out.len(), index.len());
        assert!(out
            .iter()
            .zip(&index)
            .all(|(o, &i)| *o == source[i as usize]));
    }

    /// An index past the source panics, as indexing would, wherever it is in its chunk.
    #[test]
    #[should_panic(expected = "a gather index past the source")]
    fn a_gather_index_past_the_source_panics() {
        let source = [[1.0f32; 3]; 10];
        let mut index = vec![0u32; CHUNK + 5];
        index[CHUNK + 3] = 10;
        let _ = gather_indexed(&source, &index);
    }
}
