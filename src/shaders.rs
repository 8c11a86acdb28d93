//! The compute shaders of `glsl/*.comp`, compiled to SPIR-V by `build.rs`. One constant per
//! entry point, named after its file (`glsl/disk_blur.comp` -> [`DISK_BLUR`]).

/// A compiled compute shader and the workgroup size read back from its SPIR-V.
#[derive(Clone, Copy, Debug)]
pub struct ShaderSource {
    pub name: &'static str,
    pub local_size: [u32; 3],
    pub spirv: &'static [u32],
}

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
