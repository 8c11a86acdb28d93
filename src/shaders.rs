//! The compute shaders of `glsl/*.comp`, compiled to SPIR-V by `build.rs`. One constant per
//! entry point, named after its file (`glsl/disk_blur.comp` -> [`DISK_BLUR`]).

/// A compiled compute shader and what `build.rs` read back from its SPIR-V: the workgroup
/// size and the kind of each binding of set 0.
#[derive(Clone, Copy, Debug)]
pub struct ShaderSource {
    pub name: &'static str,
    pub local_size: [u32; 3],
    /// Bit b set: binding b is a storage buffer.
    pub storage_bindings: u32,
    /// Bit b set: binding b is a uniform texel buffer (`samplerBuffer`).
    pub texel_bindings: u32,
    pub spirv: &'static [u32],
}

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
