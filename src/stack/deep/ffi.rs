//! The only place that calls OpenEXR's core C library (`libOpenEXRCore`, Debian's
//! `libopenexr-dev` 3.1) and the only `unsafe` of the deep reader: hand-written bindings of
//! the few functions it needs, and a safe [`DeepFile`] over them that hands back owned Rust
//! values (headers, one chunk's sample counts and its decompressed bytes).
//!
//! The library is used to parse headers, read chunks and decompress them, never to unpack
//! samples: OpenEXR 3.1's deep unpacker overflows the heap on crafted sample counts
//! (CVE-2023-5841), so the decoder's unpack step is switched off and the caller
//! ([`super::read`]) checks every count against the data window, the chunk's own sizes and
//! its sample budget before it touches a byte. Chunk sizes are checked here before the
//! library allocates for them.
#![allow(unsafe_code)]
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::Path;

type ExrResult = i32;
type Context = *mut c_void;

const STORAGE_DEEP_SCANLINE: c_int = 2;
const STORAGE_DEEP_TILED: c_int = 3;
const ATTR_LIST_FILE_ORDER: c_int = 0;
/// `exr_attribute_type_t` values we print into the attribute map (openexr_attr.h: UNKNOWN is
/// 0, then BOX2I, BOX2F, CHLIST, CHROMATICITIES, COMPRESSION, DOUBLE = 6, ..., STRING = 19).
const ATTR_FLOAT: c_int = 8;
const ATTR_DOUBLE: c_int = 6;
const ATTR_INT: c_int = 10;
const ATTR_STRING: c_int = 19;

#[repr(C)]
struct ContextInitializer {
    size: usize,
    error_handler_fn: Option<extern "C" fn(*const c_void, ExrResult, *const c_char)>,
    alloc_fn: *const c_void,
    free_fn: *const c_void,
    user_data: *mut c_void,
    read_fn: *const c_void,
    size_fn: *const c_void,
    write_fn: *const c_void,
    destroy_fn: *const c_void,
    max_image_width: c_int,
    max_image_height: c_int,
    max_tile_width: c_int,
    max_tile_height: c_int,
    zip_level: c_int,
    dwa_quality: f32,
    flags: c_int,
}

#[repr(C)]
#[derive(Clone, Copy, Default)]
struct Box2i {
    min: [i32; 2],
    max: [i32; 2],
}

#[repr(C)]
struct AttrString {
    length: i32,
    alloc_size: i32,
    str: *const c_char,
}

#[repr(C)]
struct ChannelListEntry {
    name: AttrString,
    pixel_type: c_int,
    p_linear: u8,
    reserved: [u8; 3],
    x_sampling: i32,
    y_sampling: i32,
}

#[repr(C)]
struct ChannelList {
    num_channels: c_int,
    num_alloced: c_int,
    entries: *const ChannelListEntry,
}

#[repr(C)]
struct Attribute {
    name: *const c_char,
    type_name: *const c_char,
    name_length: u8,
    type_name_length: u8,
    pad: [u8; 2],
    kind: c_int,
    value: AttributeValue,
}

#[repr(C)]
union AttributeValue {
    f: f32,
    d: f64,
    i: i32,
    string: *const AttrString,
    raw: *const u8,
}

#[repr(C)]
#[derive(Clone, Copy)]
struct ChunkInfo {
    idx: i32,
    start_x: i32,
    start_y: i32,
    height: i32,
    width: i32,
    level_x: u8,
    level_y: u8,
    kind: u8,
    compression: u8,
    data_offset: u64,
    packed_size: u64,
    unpacked_size: u64,
    sample_count_data_offset: u64,
    sample_count_table_size: u64,
}

#[repr(C)]
struct CodingChannelInfo {
    channel_name: *const c_char,
    height: i32,
    width: i32,
    x_samples: i32,
    y_samples: i32,
    p_linear: u8,
    bytes_per_element: i8,
    data_type: u16,
    user_bytes_per_element: i16,
    user_data_type: u16,
    user_pixel_stride: i32,
    user_line_stride: i32,
    decode_to_ptr: *mut u8,
}

type PipelineFn = Option<unsafe extern "C" fn(*mut DecodePipeline) -> ExrResult>;

#[repr(C)]
struct DecodePipeline {
    channels: *mut CodingChannelInfo,
    channel_count: i16,
    decode_flags: u16,
    part_index: c_int,
    context: Context,
    chunk: ChunkInfo,
    decoding_user_data: *mut c_void,
    packed_buffer: *mut c_void,
    packed_alloc_size: usize,
    unpacked_buffer: *mut c_void,
    unpacked_alloc_size: usize,
    packed_sample_count_table: *mut c_void,
    packed_sample_count_alloc_size: usize,
    sample_count_table: *mut i32,
    sample_count_alloc_size: usize,
    scratch_buffer_1: *mut c_void,
    scratch_alloc_size_1: usize,
    scratch_buffer_2: *mut c_void,
    scratch_alloc_size_2: usize,
    alloc_fn: *const c_void,
    free_fn: *const c_void,
    read_fn: PipelineFn,
    decompress_fn: PipelineFn,
    realloc_nonimage_data_fn: PipelineFn,
    unpack_and_convert_fn: PipelineFn,
    quick_chan_store: [CodingChannelInfo; 5],
}

#[link(name = "OpenEXRCore-3_1")]
extern "C" {
    fn exr_start_read(ctxt: *mut Context, filename: *const c_char, init: *const ContextInitializer) -> ExrResult;
    fn exr_finish(ctxt: *mut Context) -> ExrResult;
    fn exr_get_count(ctxt: Context, count: *mut c_int) -> ExrResult;
    fn exr_get_name(ctxt: Context, part: c_int, out: *mut *const c_char) -> ExrResult;
    fn exr_get_storage(ctxt: Context, part: c_int, out: *mut c_int) -> ExrResult;
    fn exr_get_data_window(ctxt: Context, part: c_int, out: *mut Box2i) -> ExrResult;
    fn exr_get_display_window(ctxt: Context, part: c_int, out: *mut Box2i) -> ExrResult;
    fn exr_get_channels(ctxt: Context, part: c_int, out: *mut *const ChannelList) -> ExrResult;
    fn exr_get_compression(ctxt: Context, part: c_int, out: *mut c_int) -> ExrResult;
    fn exr_get_scanlines_per_chunk(ctxt: Context, part: c_int, out: *mut i32) -> ExrResult;
    fn exr_get_tile_sizes(ctxt: Context, part: c_int, lx: c_int, ly: c_int, w: *mut i32, h: *mut i32) -> ExrResult;
    fn exr_get_attribute_count(ctxt: Context, part: c_int, count: *mut i32) -> ExrResult;
    fn exr_get_attribute_by_index(
        ctxt: Context,
        part: c_int,
        mode: c_int,
        idx: i32,
        out: *mut *const Attribute,
    ) -> ExrResult;
    fn exr_read_scanline_chunk_info(ctxt: Context, part: c_int, y: c_int, info: *mut ChunkInfo) -> ExrResult;
    fn exr_read_tile_chunk_info(
        ctxt: Context,
        part: c_int,
        tx: c_int,
        ty: c_int,
        lx: c_int,
        ly: c_int,
        info: *mut ChunkInfo,
    ) -> ExrResult;
    fn exr_decoding_initialize(
        ctxt: Context,
        part: c_int,
        info: *const ChunkInfo,
        decode: *mut DecodePipeline,
    ) -> ExrResult;
    fn exr_decoding_choose_default_routines(ctxt: Context, part: c_int, decode: *mut DecodePipeline) -> ExrResult;
    fn exr_decoding_run(ctxt: Context, part: c_int, decode: *mut DecodePipeline) -> ExrResult;
    fn exr_decoding_destroy(ctxt: Context, decode: *mut DecodePipeline) -> ExrResult;
    fn exr_get_default_error_message(code: ExrResult) -> *const c_char;
}

thread_local! {
    /// The library's last error message on this thread: its handler is called with the
    /// detailed text, the function then returns only a code.
    static LAST_ERROR: RefCell<String> = const { RefCell::new(String::new()) };
}

extern "C" fn remember_error(_ctxt: *const c_void, code: ExrResult, message: *const c_char) {
    let text = if message.is_null() {
        describe_code(code)
    } else {
        // SAFETY: the library passes a NUL-terminated message valid for this call.
        unsafe { CStr::from_ptr(message) }.to_string_lossy().into_owned()
    };
    LAST_ERROR.with(|last| *last.borrow_mut() = text);
}

fn describe_code(code: ExrResult) -> String {
    // SAFETY: returns a pointer to a static NUL-terminated string for every code.
    let text = unsafe { exr_get_default_error_message(code) };
    if text.is_null() {
        return format!("OpenEXR error {code}");
    }
    // SAFETY: non-null, static and NUL-terminated (above).
    unsafe { CStr::from_ptr(text) }.to_string_lossy().into_owned()
}

/// The code as an error with the library's detailed message, if it left one.
fn check(code: ExrResult, what: &str) -> Result<(), String> {
    if code == 0 {
        return Ok(());
    }
    let detail = LAST_ERROR.with(|last| std::mem::take(&mut *last.borrow_mut()));
    let detail = if detail.is_empty() { describe_code(code) } else { detail };
    Err(format!("{what}: {detail}"))
}

/// Sample storage of one deep channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChannelType {
    Uint,
    Half,
    Float,
}

impl ChannelType {
    pub fn bytes(self) -> usize {
        match self {
            ChannelType::Half => 2,
            ChannelType::Uint | ChannelType::Float => 4,
        }
    }
}

/// One part's header, as far as the deep reader needs it.
#[derive(Clone, Debug)]
pub struct PartHeader {
    pub name: Option<String>,
    /// Deep tiled (else deep scanline); None for a part that is not deep.
    pub deep_tiled: Option<bool>,
    /// Inclusive corners, as the file stores them.
    pub data_window: [i32; 4],
    pub display_window: [i32; 4],
    /// In the file's (sorted) order, which is also the order of the samples in a chunk.
    pub channels: Vec<(String, ChannelType, [i32; 2])>,
    pub compression: i32,
    /// Lines per chunk (scanline) or the level-0 tile size (tiled).
    pub chunk_size: [i32; 2],
    /// Float, double, int and string attributes, printed.
    pub attributes: BTreeMap<String, String>,
}

/// One decoded chunk: its rectangle, the per-line cumulative sample counts as the file stores
/// them (unchecked), and the decompressed sample bytes (per line, per channel, per pixel).
pub struct RawChunk {
    pub start: [i32; 2],
    pub size: [i32; 2],
    pub cumulative_counts: Vec<i32>,
    pub data: Vec<u8>,
}

/// An open file. Dropping it closes the file.
pub struct DeepFile {
    context: Context,
    file_size: u64,
}

impl Drop for DeepFile {
    fn drop(&mut self) {
        // SAFETY: `context` came from a successful exr_start_read and is finished once.
        unsafe { exr_finish(&mut self.context) };
    }
}

impl DeepFile {
    pub fn open(path: &Path) -> Result<Self, String> {
        let file_size = std::fs::metadata(path).map_err(|e| e.to_string())?.len();
        let name =
            CString::new(path.as_os_str().as_encoded_bytes()).map_err(|_| "the path holds a NUL byte".to_string())?;
        let init = ContextInitializer {
            size: std::mem::size_of::<ContextInitializer>(),
            error_handler_fn: Some(remember_error),
            alloc_fn: std::ptr::null(),
            free_fn: std::ptr::null(),
            user_data: std::ptr::null_mut(),
            read_fn: std::ptr::null(),
            size_fn: std::ptr::null(),
            write_fn: std::ptr::null(),
            destroy_fn: std::ptr::null(),
            max_image_width: 0,
            max_image_height: 0,
            max_tile_width: 0,
            max_tile_height: 0,
            zip_level: -1,
            dwa_quality: -1.0,
            flags: 0,
        };
        let mut context: Context = std::ptr::null_mut();
        // SAFETY: `name` is NUL-terminated, `init` is a complete v3 initializer whose size field
        // says so, and `context` receives the handle (null on failure).
        let code = unsafe { exr_start_read(&mut context, name.as_ptr(), &init) };
        if code != 0 {
            if !context.is_null() {
                // SAFETY: a context the failed call left allocated is released once.
                unsafe { exr_finish(&mut context) };
            }
            return Err(check(code, "not a readable OpenEXR file").unwrap_err());
        }
        Ok(Self { context, file_size })
    }

    pub fn part_count(&self) -> Result<usize, String> {
        let mut count = 0;
        // SAFETY: valid context, out-pointer to a local.
        check(unsafe { exr_get_count(self.context, &mut count) }, "part count")?;
        Ok(count.max(0) as usize)
    }

    pub fn header(&self, part: usize) -> Result<PartHeader, String> {
        let ctx = self.context;
        let p = part as c_int;
        let mut storage = 0;
        // SAFETY (this block's calls): valid context, part index below exr_get_count, and
        // out-pointers to locals; returned pointers refer to the context's header, valid until
        // exr_finish, and are copied into owned values before this function returns.
        unsafe {
            check(exr_get_storage(ctx, p, &mut storage), "part storage")?;
            let mut name_ptr: *const c_char = std::ptr::null();
            let name = if exr_get_name(ctx, p, &mut name_ptr) == 0 && !name_ptr.is_null() {
                Some(CStr::from_ptr(name_ptr).to_string_lossy().into_owned())
            } else {
                LAST_ERROR.with(|last| last.borrow_mut().clear());
                None
            };
            let (mut data, mut display) = (Box2i::default(), Box2i::default());
            check(exr_get_data_window(ctx, p, &mut data), "data window")?;
            check(exr_get_display_window(ctx, p, &mut display), "display window")?;
            let mut list: *const ChannelList = std::ptr::null();
            check(exr_get_channels(ctx, p, &mut list), "channel list")?;
            let mut channels = Vec::new();
            if !list.is_null() && !(*list).entries.is_null() {
                for c in 0..(*list).num_channels.max(0) as usize {
                    let entry = &*(*list).entries.add(c);
                    let name = CStr::from_ptr(entry.name.str).to_string_lossy().into_owned();
                    let kind = match entry.pixel_type {
                        0 => ChannelType::Uint,
                        1 => ChannelType::Half,
                        _ => ChannelType::Float,
                    };
                    channels.push((name, kind, [entry.x_sampling, entry.y_sampling]));
                }
            }
            let mut compression = 0;
            check(exr_get_compression(ctx, p, &mut compression), "compression")?;
            let deep_tiled = match storage {
                STORAGE_DEEP_SCANLINE => Some(false),
                STORAGE_DEEP_TILED => Some(true),
                _ => None,
            };
            let mut chunk_size = [1, 1];
            match deep_tiled {
                Some(false) => check(exr_get_scanlines_per_chunk(ctx, p, &mut chunk_size[1]), "lines per chunk")?,
                Some(true) => {
                    check(exr_get_tile_sizes(ctx, p, 0, 0, &mut chunk_size[0], &mut chunk_size[1]), "tile size")?
                }
                None => {}
            }
            Ok(PartHeader {
                name,
                deep_tiled,
                data_window: [data.min[0], data.min[1], data.max[0], data.max[1]],
                display_window: [display.min[0], display.min[1], display.max[0], display.max[1]],
                channels,
                compression,
                chunk_size,
                attributes: self.attributes(p)?,
            })
        }
    }

    fn attributes(&self, part: c_int) -> Result<BTreeMap<String, String>, String> {
        let mut count = 0;
        // SAFETY: valid context and part, out-pointer to a local.
        check(unsafe { exr_get_attribute_count(self.context, part, &mut count) }, "attribute count")?;
        let mut out = BTreeMap::new();
        for i in 0..count {
            let mut attr: *const Attribute = std::ptr::null();
            // SAFETY: index below the count just read; the attribute lives as long as the context
            // and its name, kind and value are copied out at once; the union member read is the
            // one its `kind` names.
            unsafe {
                check(exr_get_attribute_by_index(self.context, part, ATTR_LIST_FILE_ORDER, i, &mut attr), "attribute")?;
                if attr.is_null() || (*attr).name.is_null() {
                    continue;
                }
                let a = &*attr;
                let value = match a.kind {
                    ATTR_FLOAT => a.value.f.to_string(),
                    ATTR_DOUBLE => a.value.d.to_string(),
                    ATTR_INT => a.value.i.to_string(),
                    ATTR_STRING if !a.value.string.is_null() && !(*a.value.string).str.is_null() => {
                        let s = &*a.value.string;
                        let bytes = std::slice::from_raw_parts(s.str.cast::<u8>(), s.length.max(0) as usize);
                        String::from_utf8_lossy(bytes).into_owned()
                    }
                    _ => continue,
                };
                out.insert(CStr::from_ptr(a.name).to_string_lossy().into_owned(), value);
            }
        }
        Ok(out)
    }

    /// Reads and decompresses one chunk of a deep part: the scanline block starting at line
    /// `y`, or the level-0 tile `(tx, ty)`. Refused before the library allocates: a chunk
    /// outside the data window, a sample table larger than the chunk's pixels need, packed
    /// sizes beyond the file, unpacked data beyond `max_unpacked_bytes`.
    /// `tile_size` is the level-0 tile size of a tiled part: the chunk's pixel position is
    /// computed from it (OpenEXR 3.1 reports a tile's indices where a scanline chunk has its
    /// position).
    pub fn read_chunk(
        &self,
        part: usize,
        tile_size: Option<[i32; 2]>,
        at: [i32; 2],
        data_window: [i32; 4],
        max_unpacked_bytes: u64,
    ) -> Result<RawChunk, String> {
        let tiled = tile_size.is_some();
        let p = part as c_int;
        let mut info = std::mem::MaybeUninit::<ChunkInfo>::zeroed();
        // SAFETY: valid context and part; `info` is plain data the call fills.
        let code = unsafe {
            if tiled {
                exr_read_tile_chunk_info(self.context, p, at[0], at[1], 0, 0, info.as_mut_ptr())
            } else {
                exr_read_scanline_chunk_info(self.context, p, at[1], info.as_mut_ptr())
            }
        };
        check(code, "chunk table")?;
        // SAFETY: zero-initialised plain data, filled by the successful call.
        let mut info = unsafe { info.assume_init() };
        let [x0, y0, x1, y1] = data_window;
        if let Some([tw, th]) = tile_size {
            info.start_x = (i64::from(x0) + i64::from(at[0]) * i64::from(tw)).clamp(0, i64::from(i32::MAX)) as i32;
            info.start_y = (i64::from(y0) + i64::from(at[1]) * i64::from(th)).clamp(0, i64::from(i32::MAX)) as i32;
        }
        let inside = info.width > 0
            && info.height > 0
            && info.start_x >= x0
            && info.start_y >= y0
            && i64::from(info.start_x) + i64::from(info.width) - 1 <= i64::from(x1)
            && i64::from(info.start_y) + i64::from(info.height) - 1 <= i64::from(y1);
        if !inside {
            return Err(format!(
                "chunk at ({}, {}) of {}x{} pixels lies outside the data window",
                info.start_x, info.start_y, info.width, info.height
            ));
        }
        let pixels = u64::from(info.width as u32) * u64::from(info.height as u32);
        // A compressed table is never much larger than the raw one (zlib's worst case adds a
        // few bytes per 16 KiB); anything larger is forged.
        let table_limit = pixels * 4 + 1024 + pixels / 8;
        if info.sample_count_table_size > table_limit
            || info.packed_size > self.file_size
            || info.sample_count_table_size > self.file_size
        {
            return Err(format!(
                "chunk at ({}, {}) declares {} bytes of sample counts and {} packed bytes, more than the file or its {} pixels can hold",
                info.start_x, info.start_y, info.sample_count_table_size, info.packed_size, pixels
            ));
        }
        if info.unpacked_size > max_unpacked_bytes {
            return Err(format!(
                "chunk at ({}, {}) declares {} bytes of samples, more than the sample budget allows ({max_unpacked_bytes} bytes)",
                info.start_x, info.start_y, info.unpacked_size
            ));
        }
        let mut decode = std::mem::MaybeUninit::<DecodePipeline>::zeroed();
        let ctx = self.context;
        // SAFETY: `decode` is zeroed (the library's own initial state, EXR_DECODE_PIPELINE_INITIALIZER)
        // and initialised by exr_decoding_initialize before use; it is destroyed on every path
        // after a successful initialize. The unpack step is set to none, so the library only
        // reads and decompresses into its own buffers; their sizes come from `info`, checked
        // above. The sample table has width*height entries once the run succeeded, and the
        // unpacked buffer `info.unpacked_size` bytes (null when 0); both are copied out before
        // the pipeline is destroyed.
        unsafe {
            check(exr_decoding_initialize(ctx, p, &info, decode.as_mut_ptr()), "decoder")?;
            let decode = &mut *decode.as_mut_ptr();
            let result = (|| {
                check(exr_decoding_choose_default_routines(ctx, p, decode), "decoder")?;
                decode.decode_flags = 0;
                decode.unpack_and_convert_fn = None;
                decode.realloc_nonimage_data_fn = None;
                check(
                    exr_decoding_run(ctx, p, decode),
                    &format!("chunk at pixel ({}, {})", info.start_x, info.start_y),
                )
                .map_err(|e| {
                    // The library checks the count table too (it must not decrease along a line,
                    // nor count more than the chunk holds) and says only this.
                    if e.contains("sample table") || e.contains("sample count") {
                        format!("{e}: the sample count table is inconsistent with the data")
                    } else {
                        e
                    }
                })?;
                let counts = if pixels == 0 || decode.sample_count_table.is_null() {
                    return Err("chunk has no sample count table".to_string());
                } else {
                    std::slice::from_raw_parts(decode.sample_count_table, pixels as usize).to_vec()
                };
                let data = if info.unpacked_size == 0 || decode.unpacked_buffer.is_null() {
                    Vec::new()
                } else {
                    std::slice::from_raw_parts(decode.unpacked_buffer.cast::<u8>(), info.unpacked_size as usize)
                        .to_vec()
                };
                Ok(RawChunk {
                    start: [info.start_x, info.start_y],
                    size: [info.width, info.height],
                    cumulative_counts: counts,
                    data,
                })
            })();
            exr_decoding_destroy(ctx, decode);
            result
        }
    }
}
