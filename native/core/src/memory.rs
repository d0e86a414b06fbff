//! Memory: fallible allocation of every buffer whose size scales with the request, and the
//! memory this process can have (the machine's physical memory, capped by a cgroup limit).
//!
//! Rust's `vec!`, `Vec::with_capacity` and `collect` abort the process when the allocator
//! refuses (and Linux refuses a single allocation beyond what it could ever back, or any
//! allocation past an address-space limit). The functions here ask with `try_reserve_exact`
//! instead and turn a refusal into [`Error::OutOfMemory`] with the bytes asked for and the
//! memory available, which the Python binding raises as `MemoryBudgetError`. They cost what
//! the infallible forms cost: one allocation, and zeroed buffers come from `alloc_zeroed` as
//! `vec![0; n]` does (fresh pages from the system are not written, but memory the allocator
//! reuses is, as the Python extension's allocator, mimalloc, does with memory freed in the last
//! second: a buffer that is written whole is better made uninitialised).
//!
//! Under an address-space limit (`ulimit -v`, `RLIMIT_AS`) the large requests here also keep
//! [`ADDRESS_SPACE_HEADROOM`] of the address space free: the small allocations that nothing can
//! make fallible (a vector's growth inside a walk, rayon's jobs, a worker thread's `malloc`
//! arena, which maps 64 MiB at a time) would otherwise be the ones to find no room, and abort.
//! The headroom was measured with glibc's `malloc`. The Python extension allocates through
//! mimalloc, which reserves address space up to 1 GiB at a time and asks for less when refused;
//! with it, the fuzzer's cases under such limits ended typed too (`scripts/fuzz.sh 6`,
//! 2026-12-05: 3,908 cases, none aborted), but its behaviour near the limit was not analysed.
//!
//! The budget check of a request before any work ([`check_request`]) compares its estimate with
//! the budget and with the machine's memory: a budget raised above the memory the machine has
//! does not let a request in that the kernel would end with the OOM killer (overcommit lets
//! the allocations succeed; touching the pages kills the process).

use std::alloc::{alloc_zeroed, Layout};
use std::sync::OnceLock;

use crate::error::{Error, Result};

/// The error of a refused allocation of `count` values of `T`.
fn refused<T>(count: usize) -> Error {
    refused_bytes(bytes_of::<T>(count))
}

/// The error of a refused allocation of `required` bytes (for containers these helpers do not
/// make, e.g. a hash set's `try_reserve`).
pub(crate) fn refused_bytes(required: u64) -> Error {
    Error::OutOfMemory {
        required,
        available: available_memory(),
    }
}

/// Address space left free under an address-space limit by every request of at least
/// [`CHECKED_BYTES`] (module documentation): refused when it would leave less. Measured
/// (2026-12-05, the fuzzer's harness forked under `RLIMIT_AS`, two threads): without it, a
/// plan's limit and smooth UVs of degree 6 at 8 levels of a cube aborted on a 122,880-byte
/// allocation at 240 MiB, degree 9 at 7 levels on a 6,144-byte one at 160 MiB, where every
/// other limit nearby ended typed.
pub const ADDRESS_SPACE_HEADROOM: u64 = 64 << 20;

/// Requests from this size on are checked against the address-space limit (a read of
/// `/proc/self/statm`, only when a limit is set); smaller ones leave the headroom to cover them.
const CHECKED_BYTES: u64 = 1 << 20;

/// `Ok` when `more` values of `T` leave [`ADDRESS_SPACE_HEADROOM`] free under the process's
/// address-space limit (always when there is none, or below [`CHECKED_BYTES`]), else the error
/// of a refused request for `asked` values.
fn headroom<T>(more: usize, asked: usize) -> Result<()> {
    let bytes = bytes_of::<T>(more);
    match bytes < CHECKED_BYTES || headroom_left(bytes, address_space_limit(), address_space_used) {
        true => Ok(()),
        false => Err(refused::<T>(asked)),
    }
}

/// Whether a request of `bytes` leaves the headroom under `limit`; `used` is read only when
/// there is one, and a size it cannot tell lets the allocator decide.
fn headroom_left(bytes: u64, limit: Option<u64>, used: impl FnOnce() -> Option<u64>) -> bool {
    let Some(limit) = limit else { return true };
    used().is_none_or(|used| {
        used.saturating_add(bytes)
            .saturating_add(ADDRESS_SPACE_HEADROOM)
            <= limit
    })
}

/// `count` values of `T` in bytes (saturating).
fn bytes_of<T>(count: usize) -> u64 {
    (count as u128 * std::mem::size_of::<T>() as u128).min(u64::MAX as u128) as u64
}

/// An empty vector with room for `capacity` values, or [`Error::OutOfMemory`].
pub fn with_capacity<T>(capacity: usize) -> Result<Vec<T>> {
    headroom::<T>(capacity, capacity)?;
    let mut v = Vec::new();
    v.try_reserve_exact(capacity)
        .map_err(|_| refused::<T>(capacity))?;
    Ok(v)
}

/// Room for `additional` more values in `v` (exactly; see [`Vec::try_reserve_exact`]), or
/// [`Error::OutOfMemory`].
pub fn reserve<T>(v: &mut Vec<T>, additional: usize) -> Result<()> {
    let total = v.len().saturating_add(additional);
    headroom::<T>(total.saturating_sub(v.capacity()), total)?;
    v.try_reserve_exact(additional)
        .map_err(|_| refused::<T>(total))
}

/// Room for `additional` more values in `v`, growing it geometrically as `push` and `extend`
/// do (at least doubling when full), or [`Error::OutOfMemory`]: for vectors filled a few items
/// at a time, where [`reserve`]'s exact growth would reallocate on every call (the limit
/// tiles' lists did: a tenth of a first limit call's instructions in `malloc`).
pub fn grow<T>(v: &mut Vec<T>, additional: usize) -> Result<()> {
    let total = v.len().saturating_add(additional);
    if total > v.capacity() {
        // Growth at least doubles the capacity.
        headroom::<T>(total.max(2 * v.capacity()) - v.capacity(), total)?;
    }
    v.try_reserve(additional).map_err(|_| refused::<T>(total))
}

/// `len` copies of `value` (`vec![value; len]`), or [`Error::OutOfMemory`]. For zeros use
/// [`zeroed`], which does not write fresh pages.
pub fn filled<T: Clone>(len: usize, value: T) -> Result<Vec<T>> {
    let mut v = with_capacity(len)?;
    v.resize(len, value);
    Ok(v)
}

/// `len` zero values (`vec![0; len]`, from `alloc_zeroed`), or [`Error::OutOfMemory`].
pub fn zeroed<T: Zeroable>(len: usize) -> Result<Vec<T>> {
    let layout = Layout::array::<T>(len).map_err(|_| refused::<T>(len))?;
    headroom::<T>(len, len)?;
    if layout.size() == 0 {
        let mut v = Vec::new();
        // Zero-sized values or `len == 0`: no allocation; `resize` only sets the length.
        v.resize_with(len, || unreachable_zero::<T>());
        return Ok(v);
    }
    // SAFETY: the layout has a non-zero size; a non-null result is an allocation of exactly
    // `layout` from the global allocator, all bytes zero, which `T: Zeroable` says is a valid
    // `T` for each of the `len` values; capacity and length are `len`, as allocated.
    unsafe {
        let ptr = alloc_zeroed(layout) as *mut T;
        if ptr.is_null() {
            return Err(refused::<T>(len));
        }
        Ok(Vec::from_raw_parts(ptr, len, len))
    }
}

/// The zero of a zero-sized `Zeroable` type (only reached for those).
fn unreachable_zero<T: Zeroable>() -> T {
    // SAFETY: `T: Zeroable` (all-zero bytes are a valid `T`); zero-sized here, so no bytes.
    unsafe { std::mem::zeroed() }
}

/// The values of `iter`, collected into one allocation sized by the iterator's lower bound
/// (exact for maps over slices and ranges), or [`Error::OutOfMemory`]. An iterator that yields
/// more than its lower bound (a `filter`) grows the vector infallibly past it: give those an
/// upper bound with [`with_capacity`] and `extend`.
pub fn collect<T>(iter: impl IntoIterator<Item = T>) -> Result<Vec<T>> {
    let iter = iter.into_iter();
    let mut v = with_capacity(iter.size_hint().0)?;
    v.extend(iter);
    Ok(v)
}

/// Types whose all-zero bytes are a valid value (what [`zeroed`] may hand out).
///
/// # Safety
/// Implement only for types for which all-zero bytes are a valid, initialised value.
pub unsafe trait Zeroable {}

// SAFETY: all-zero bytes are 0, 0.0 or false for each of these, and an array of such values.
unsafe impl Zeroable for u8 {}
unsafe impl Zeroable for u16 {}
unsafe impl Zeroable for u32 {}
unsafe impl Zeroable for u64 {}
unsafe impl Zeroable for usize {}
unsafe impl Zeroable for i32 {}
unsafe impl Zeroable for i64 {}
unsafe impl Zeroable for f32 {}
unsafe impl Zeroable for f64 {}
unsafe impl Zeroable for bool {}
unsafe impl<T: Zeroable, const N: usize> Zeroable for [T; N] {}

/// Refuses a request estimated at `required` bytes (`faces` output faces) before any work:
/// [`Error::MemoryBudget`] over `budget`, [`Error::OutOfMemory`] over the memory the machine
/// has ([`machine_memory`]), so that a budget raised above it is still refused cleanly.
pub fn check_request(required: u64, faces: u64, budget: u64) -> Result<()> {
    if required > budget {
        return Err(Error::MemoryBudget {
            required,
            budget,
            faces,
        });
    }
    match machine_memory() {
        Some(machine) if required > machine => Err(Error::OutOfMemory {
            required,
            available: machine,
        }),
        _ => Ok(()),
    }
}

/// The default memory budget: [`crate::DEFAULT_MEMORY_BUDGET`] (4 GiB), or the machine's
/// memory ([`machine_memory`]) when it has less.
pub fn default_memory_budget() -> u64 {
    let default = crate::options::DEFAULT_MEMORY_BUDGET;
    machine_memory().map_or(default, |m| m.min(default))
}

/// The memory this process can have: the machine's physical memory, or the memory limit of
/// its cgroup (and of the cgroups above it) when lower; `None` where it cannot be read
/// (other systems than Linux, a `/proc` that is not there). Read once and kept.
pub fn machine_memory() -> Option<u64> {
    static MEMORY: OnceLock<Option<u64>> = OnceLock::new();
    *MEMORY.get_or_init(read_machine_memory)
}

/// The memory figure errors report: [`machine_memory`], or the address-space limit when it is
/// lower (an allocation refused under `ulimit -v`), `u64::MAX` when neither is known.
fn available_memory() -> u64 {
    let machine = machine_memory().unwrap_or(u64::MAX);
    machine.min(address_space_limit().unwrap_or(u64::MAX))
}

#[cfg(target_os = "linux")]
fn address_space_limit() -> Option<u64> {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: `getrlimit` writes the limit into the struct we own.
    let ok = unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut limit) } == 0;
    (ok && limit.rlim_cur != libc::RLIM_INFINITY).then_some(limit.rlim_cur)
}

#[cfg(not(target_os = "linux"))]
fn address_space_limit() -> Option<u64> {
    None
}

/// The address space this process maps now (`VmSize`: the first field of `/proc/self/statm`,
/// in pages), read into a buffer on the stack: this runs before large allocations, when a
/// small one may be what fails.
#[cfg(target_os = "linux")]
fn address_space_used() -> Option<u64> {
    use std::io::Read;
    let mut buffer = [0u8; 128];
    let n = std::fs::File::open("/proc/self/statm")
        .and_then(|mut f| f.read(&mut buffer))
        .ok()?;
    let pages: u64 = std::str::from_utf8(&buffer[..n])
        .ok()?
        .split_ascii_whitespace()
        .next()?
        .parse()
        .ok()?;
    // SAFETY: `sysconf` reads a system constant.
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    u64::try_from(page)
        .ok()
        .map(|page| pages.saturating_mul(page))
}

#[cfg(not(target_os = "linux"))]
fn address_space_used() -> Option<u64> {
    None
}

#[cfg(target_os = "linux")]
fn read_machine_memory() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let physical = meminfo_total(&meminfo)?;
    let cgroups = std::fs::read_to_string("/proc/self/cgroup").unwrap_or_default();
    Some(
        cgroup_limits(&cgroups, |path| std::fs::read_to_string(path).ok())
            .map_or(physical, |c| c.min(physical)),
    )
}

/// Not read on other systems: the budget alone (4 GiB by default) holds.
#[cfg(not(target_os = "linux"))]
fn read_machine_memory() -> Option<u64> {
    None
}

/// `MemTotal` of `/proc/meminfo`, in bytes.
fn meminfo_total(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// The lowest memory limit of the process's cgroups (`/proc/self/cgroup` given as `cgroups`)
/// and their ancestors, in cgroup v2 (`memory.max`, also under a hybrid `unified` mount) and
/// v1 (`memory.limit_in_bytes`); `read` reads a file. "max" and v1's "unlimited"
/// (about 2^63) are no limit. A cgroup namespace shows the process at `/`: the mount's root
/// file is then its own limit, and walking up from the process's path always reaches it.
fn cgroup_limits(cgroups: &str, read: impl Fn(&str) -> Option<String>) -> Option<u64> {
    let mut lowest: Option<u64> = None;
    for line in cgroups.lines() {
        let mut fields = line.splitn(3, ':');
        let (Some(_), Some(controllers), Some(path)) =
            (fields.next(), fields.next(), fields.next())
        else {
            continue;
        };
        let places: &[(&str, &str)] = if controllers.is_empty() {
            &[
                ("/sys/fs/cgroup", "memory.max"),
                ("/sys/fs/cgroup/unified", "memory.max"),
            ]
        } else if controllers.split(',').any(|c| c == "memory") {
            &[("/sys/fs/cgroup/memory", "memory.limit_in_bytes")]
        } else {
            continue;
        };
        for (mount, file) in places {
            let mut dir = path.trim_end_matches('/');
            loop {
                let limit = read(&format!("{mount}{dir}/{file}"))
                    .and_then(|text| text.trim().parse::<u64>().ok())
                    .filter(|&bytes| bytes < 1 << 62);
                if let Some(bytes) = limit {
                    lowest = Some(lowest.map_or(bytes, |l| l.min(bytes)));
                }
                match dir.rfind('/') {
                    Some(cut) => dir = &dir[..cut],
                    None => break,
                }
            }
        }
    }
    lowest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_requests_leave_the_headroom_under_a_limit() {
        let (mib, headroom) = (1u64 << 20, ADDRESS_SPACE_HEADROOM);
        let unread = || -> Option<u64> { panic!("no limit: nothing to read") };
        assert!(headroom_left(u64::MAX, None, unread));
        let limit = Some(1000 * mib);
        // 100 MiB mapped: a request may take what leaves exactly the headroom, not a byte more.
        let used = || Some(100 * mib);
        assert!(headroom_left(900 * mib - headroom, limit, used));
        assert!(!headroom_left(900 * mib - headroom + 1, limit, used));
        assert!(!headroom_left(u64::MAX, limit, used));
        // The mapped size unknown: only the allocator decides.
        assert!(headroom_left(u64::MAX, limit, || None));
        // `VmSize` of this process, as the kernel counts it against the limit.
        assert!(address_space_used().is_some_and(|used| used > mib));
    }

    #[test]
    fn a_refused_allocation_is_an_error_not_an_abort() {
        // More than any address space: the allocator refuses at once (nothing is touched).
        // `black_box`: an allocation whose memory is never used may be optimised away (and
        // then "succeed"), which would leave `collect` and `filled` looping over it.
        use std::hint::black_box;
        let huge = black_box(usize::MAX / 16);
        for result in [
            black_box(with_capacity::<u64>(huge)).map(drop),
            black_box(zeroed::<u64>(huge)).map(drop),
            black_box(filled(huge, 1u32)).map(drop),
            black_box(collect((0..huge).map(|i| i as u64))).map(drop),
        ] {
            match result {
                Err(Error::OutOfMemory { required, .. }) => assert!(required >= huge as u64),
                other => panic!("{other:?}"),
            }
        }
        let mut v = vec![1u8];
        assert!(matches!(
            reserve(&mut v, black_box(usize::MAX / 2)),
            Err(Error::OutOfMemory { .. })
        ));
    }

    #[test]
    fn buffers_are_what_the_infallible_forms_give() {
        assert_eq!(zeroed::<u32>(5).unwrap(), vec![0u32; 5]);
        assert_eq!(zeroed::<[f64; 3]>(2).unwrap(), vec![[0.0f64; 3]; 2]);
        assert_eq!(zeroed::<u32>(0).unwrap(), Vec::<u32>::new());
        assert_eq!(zeroed::<[u8; 0]>(3).unwrap().len(), 3);
        assert_eq!(filled(3, 7u8).unwrap(), vec![7u8; 3]);
        assert_eq!(collect((0..4).map(|i| i * 2)).unwrap(), vec![0, 2, 4, 6]);
        assert_eq!(with_capacity::<u8>(9).unwrap().capacity(), 9);
    }

    #[test]
    fn a_request_over_the_budget_or_the_machine_is_refused() {
        assert!(matches!(
            check_request(2000, 10, 1000),
            Err(Error::MemoryBudget {
                required: 2000,
                budget: 1000,
                faces: 10
            })
        ));
        assert!(check_request(1000, 10, 1000).is_ok());
        if let Some(machine) = machine_memory() {
            assert!(matches!(
                check_request(machine + 1, 10, u64::MAX),
                Err(Error::OutOfMemory { available, .. }) if available == machine
            ));
            assert!(default_memory_budget() <= machine);
        }
        assert!(default_memory_budget() <= crate::DEFAULT_MEMORY_BUDGET);
    }

    #[test]
    fn meminfo_and_cgroup_limits_are_read() {
        let meminfo = "MemTotal:       24683584 kB\nMemFree:        17033056 kB\n";
        assert_eq!(meminfo_total(meminfo), Some(24683584 * 1024));
        let files = |path: &str| match path {
            "/sys/fs/cgroup/user.slice/memory.max" => Some("8589934592\n".to_string()),
            "/sys/fs/cgroup/user.slice/job/memory.max" => Some("max\n".to_string()),
            "/sys/fs/cgroup/memory/memory.limit_in_bytes" => {
                Some("9223372036854771712\n".to_string())
            }
            "/sys/fs/cgroup/memory/box/memory.limit_in_bytes" => Some("1073741824".to_string()),
            _ => None,
        };
        // v2: the parent's limit holds although the process's own cgroup says "max".
        assert_eq!(cgroup_limits("0::/user.slice/job\n", files), Some(8 << 30));
        // v1: "unlimited" at the root, 1 GiB in the process's cgroup.
        assert_eq!(
            cgroup_limits("4:memory:/box\n1:cpu:/\n", files),
            Some(1 << 30)
        );
        assert_eq!(cgroup_limits("4:memory:/\n0::/\n", files), None);
        assert_eq!(cgroup_limits("", files), None);
    }
}
