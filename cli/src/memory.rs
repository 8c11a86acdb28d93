//! The `lensblur` process's use of memory: how glibc's allocator keeps what is freed, and which
//! of its heaps the kernel backs with huge pages. Process policy, set once at start-up, so it
//! lives in the command line (a Python process keeps its own allocator). All of this file's
//! `unsafe` is allocator parameters and advice to the kernel about the heap's own pages.

/// Blocks up to 4 MiB come from the heap, and freed memory stays with the process up to 128 MiB,
/// instead of glibc's defaults: a block of 128 KiB or more mapped and unmapped for every
/// allocation, with the thresholds only growing as blocks are freed. A preview-sized render
/// allocates and frees one frame-sized buffer after another (the layering's fills and mattes,
/// each layer's sources on the CPU path), and the kernel zeroed each one again page by page.
/// Measured with `farm-bench` (15 pairs, same bytes written): a 256^2 flat RGB+Z one-shot
/// render, wall 0.177 -> 0.156 s (A/B 0.88), system time 0.104 -> 0.059 s, peak 41 -> 55 MiB;
/// the drbokeh CPU render of a five-layer 256^2 stack alone 44 -> 19 ms. The threshold stays low
/// because a larger frame's buffers are larger: at 32 MiB a 1024x768 frame's peak rose from 441
/// to 485-537 MiB (fragments of its 12 MB buffers), at 4 MiB to 447 MiB, with the 256^2 gain
/// unchanged (A/B 0.99 against 32 MiB). A resident `lensblur serve` reuses the same memory
/// request after request.
///
/// The threads also share as many heaps (arenas) as there are cores, where glibc allows eight
/// per core: the main thread and the thread pool's workers are one more than the cores, so two
/// of them share a heap and reuse what the other freed, instead of mapping and zeroing fresh
/// pages. On 2 cores (`farm-bench`, 15 pairs, the same bytes written), the 256^2 flat frame
/// focused: wall A/B 0.90, system time 0.071 -> 0.047 s, peak 56 -> 43 MiB; defocused A/B 0.93.
/// One heap for all (14,000 page faults -> 7,200) was as fast on the flat frame but made the
/// layered five-layer file 17% slower: its parallel decoding takes the one heap's lock for
/// every chunk.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn keep_freed_memory_for_reuse() {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    // SAFETY: mallopt only sets allocator parameters; it is called before any thread starts.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 4 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 128 << 20);
        libc::mallopt(libc::M_ARENA_MAX, libc::c_int::try_from(cores).unwrap_or(libc::c_int::MAX));
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn keep_freed_memory_for_reuse() {}

/// How far a heap grows at once: the main heap's first growth, and each thread heap glibc makes
/// for the pool's workers (its arenas' heaps are reserved at this size, 64 MiB on 64-bit), are
/// made whole at this size, so that [`advise_huge_pages_for_preview`] covers the pages a render
/// will use. Address space only: a page is still faulted in when first touched.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const HEAP_GROWTH: usize = 64 << 20;

/// Frames up to this many pixels are previews, whose heaps are worth backing with huge pages.
const PREVIEW_PIXELS: usize = 512 * 512;

/// Where the frame is a preview (up to 512^2), the heaps the render allocates from (the main
/// thread's, and each worker's, as first made: 64 MiB each) are backed by transparent huge
/// pages (`madvise(MADV_HUGEPAGE)`, for kernels that give them only where asked). A preview
/// touches 30-40 MiB of fresh heap, and the kernel faulted and zeroed it 4 KiB at a time, a
/// fifth of the process's CPU (`perf`, a 256^2 flat RGB+Z frame). The book's performance chapter
/// ("Live refocus") has the measurements.
///
/// Larger frames keep glibc's heaps as they are: a 1024^2 frame ran 8% faster in huge pages but
/// peaked 25% higher (each heap's 64 MiB became resident whole), and advising every large block
/// from a global allocator once cost a 4096^2 stack 7 s of system time in the kernel's
/// compaction. Best effort: where the kernel gives no huge pages, or the process's map cannot be
/// read, pages stay 4 KiB.
pub fn advise_huge_pages_for_preview(frame: Option<(usize, usize)>) {
    if is_preview(frame) {
        heaps_in_huge_pages();
    }
}

fn is_preview(frame: Option<(usize, usize)>) -> bool {
    frame.is_some_and(|(width, height)| width * height <= PREVIEW_PIXELS)
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn heaps_in_huge_pages() {
    // glibc's default padding of a heap's growth.
    const DEFAULT_TOP_PAD: libc::c_int = 128 << 10;
    // SAFETY: allocator parameters.
    unsafe {
        libc::mallopt(libc::M_TOP_PAD, HEAP_GROWTH as libc::c_int);
    }
    // The main heap grows by the padding at its next growth (a block larger than its free top),
    // and a worker's first allocation makes its heap at the padding's size; each is advised.
    advise_this_threads_heap(1 << 20);
    rayon::broadcast(|_| advise_this_threads_heap(64));
    // SAFETY: as above; later growth is glibc's usual.
    unsafe {
        libc::mallopt(libc::M_TOP_PAD, DEFAULT_TOP_PAD);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn heaps_in_huge_pages() {}

/// Advises the heap this thread allocates from (found from a block of `bytes` it allocates, in
/// the process's memory map) to be backed by huge pages, as far as [`HEAP_GROWTH`] reaches.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn advise_this_threads_heap(bytes: usize) {
    const HUGE_PAGE: usize = 2 << 20;
    // SAFETY: a block allocated and freed: the heap it came from stays mapped. (`black_box`:
    // the compiler removes a block allocated and freed unused.)
    let address = unsafe {
        let block = std::hint::black_box(libc::malloc(bytes));
        libc::free(block);
        block as usize
    };
    let Some((start, end)) = mapping_containing(address) else { return };
    let start = start.next_multiple_of(HUGE_PAGE);
    let end = end.min(start + HEAP_GROWTH) / HUGE_PAGE * HUGE_PAGE;
    if end > start {
        // SAFETY: advice about pages of this process's own heap; it cannot change their
        // contents.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

/// The start and end of the mapping in `/proc/self/maps` that holds `address`.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn mapping_containing(address: usize) -> Option<(usize, usize)> {
    let maps = std::fs::read_to_string("/proc/self/maps").ok()?;
    maps.lines().find_map(|line| {
        let (start, end) = line.split_whitespace().next()?.split_once('-')?;
        let range = (usize::from_str_radix(start, 16).ok()?, usize::from_str_radix(end, 16).ok()?);
        (range.0..range.1).contains(&address).then_some(range)
    })
}

/// What the process has used so far (`getrusage`), for the `--json` report: the benchmarks
/// read a one-shot render's memory and page faults from it.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct ProcessUsage {
    /// The most memory the process has held resident (MiB).
    pub peak_resident_mib: f64,
    /// Page faults, minor and major (a fresh page of memory, or a huge page, is one).
    pub page_faults: u64,
}

#[cfg(unix)]
pub fn usage() -> Option<ProcessUsage> {
    let mut usage = std::mem::MaybeUninit::<libc::rusage>::zeroed();
    // SAFETY: getrusage fills the structure it is given, which is read only when it succeeded.
    let usage = unsafe { (libc::getrusage(libc::RUSAGE_SELF, usage.as_mut_ptr()) == 0).then(|| usage.assume_init())? };
    // The peak from the kernel's high-water mark of this program's memory (VmHWM, as the
    // benchmarks read it): Linux carries `ru_maxrss` over from the process that started it (a
    // benchmark's 87 MiB for a render that peaked at 40). Elsewhere `ru_maxrss`, in KiB on the BSDs.
    let peak_bytes = lensblur_dev::bench::large::peak_resident_bytes().map_or(usage.ru_maxrss as f64 * 1024.0, |b| b as f64);
    Some(ProcessUsage {
        peak_resident_mib: peak_bytes / (1024.0 * 1024.0),
        page_faults: u64::try_from(usage.ru_minflt + usage.ru_majflt).unwrap_or(0),
    })
}

#[cfg(not(unix))]
pub fn usage() -> Option<ProcessUsage> {
    None
}

#[cfg(all(test, target_os = "linux", target_env = "gnu"))]
mod tests {
    use super::*;

    #[test]
    fn previews_are_frames_up_to_512_squared() {
        assert!(is_preview(Some((256, 256))) && is_preview(Some((512, 512))) && is_preview(Some((1024, 200))));
        assert!(!is_preview(Some((513, 512))) && !is_preview(Some((1024, 1024))) && !is_preview(None));
    }

    #[test]
    fn usage_counts_the_faults_of_memory_touched() {
        let before = usage().expect("getrusage works on Linux");
        let touched: Vec<u8> = vec![1; 16 << 20];
        let after = usage().unwrap();
        assert!(std::hint::black_box(&touched).iter().all(|&b| b == 1));
        assert!(after.page_faults > before.page_faults, "16 MiB touched: {before:?} -> {after:?}");
        assert!(after.peak_resident_mib >= 16.0, "{after:?}");
    }

    #[test]
    fn the_mapping_of_a_heap_block_is_found_and_holds_it() {
        let block = Box::new([7u8; 4096]);
        let address = block.as_ptr() as usize;
        let (start, end) = mapping_containing(address).expect("a heap block is mapped");
        assert!(start <= address && address + 4096 <= end);
        assert!(mapping_containing(0).is_none(), "nothing is mapped at 0");
    }
}
