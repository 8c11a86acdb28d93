//! OpenDefocus as a peer of the single-image methods: run as a separate program
//! (`dev/peers/opendefocus`, its own Cargo workspace: EUPL-1.2, never linked into lensblur), fed a
//! per-pixel signed CoC radius computed from the scene's own thin lens, so that only the
//! algorithm differs. When it cannot run, [`PeerRun::Unavailable`] says precisely why.
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

use lensblur::camera::disparity_from_z;
use lensblur::image::Image;
use lensblur::raytrace::GroundTruth;

/// Environment variable naming the peer binary; by default the release build in this checkout.
pub const OPENDEFOCUS_ENV: &str = "LENSBLUR_OPENDEFOCUS";
const MAGIC: &[u8; 8] = b"LBPEER1\0";

/// The renders of one run of the peer, or the reason there are none.
pub enum PeerRun {
    /// One render per scene with the seconds the peer measured for the render alone.
    Rendered { renders: Vec<(Image, f64)>, init_seconds: f64 },
    Unavailable(String),
}

/// Where the peer binary is: `$LENSBLUR_OPENDEFOCUS`, else `dev/peers/opendefocus/target/release`.
pub fn opendefocus_binary() -> PathBuf {
    std::env::var_os(OPENDEFOCUS_ENV).map(PathBuf::from).unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("peers/opendefocus/target/release/lensblur-peer-opendefocus")
    })
}

/// The pinhole image and its signed CoC radius in pixels (positive = nearer than focus):
/// exactly the radius every lensblur method uses for that pixel.
fn encode(truth: &GroundTruth) -> Vec<u8> {
    let image = &truth.pinhole;
    let mut out = Vec::with_capacity(16 + 20 * image.pixels.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(image.width as u32).to_le_bytes());
    out.extend_from_slice(&(image.height as u32).to_le_bytes());
    image.pixels.iter().flatten().for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
    for &z in &truth.pinhole_depth {
        out.extend_from_slice(&truth.coc.signed_radius(disparity_from_z(z)).to_le_bytes());
    }
    out
}

fn decode(bytes: &[u8], width: usize, height: usize) -> Result<Image, String> {
    let n = width * height;
    if bytes.len() != 16 + 16 * n || &bytes[..8] != MAGIC {
        return Err(format!("the peer wrote {} bytes, expected a {width}x{height} frame", bytes.len()));
    }
    let values: Vec<f32> = bytes[16..].chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    let pixels = values.chunks_exact(4).map(|p| [p[0], p[1], p[2], p[3]]).collect();
    Ok(Image { width, height, pixels })
}

/// Renders every scene with OpenDefocus in one process (one device start-up for all).
pub fn run_opendefocus(truths: &[GroundTruth]) -> PeerRun {
    match try_run(truths, &opendefocus_binary()) {
        Ok(run) => run,
        Err(reason) => PeerRun::Unavailable(reason),
    }
}

fn try_run(truths: &[GroundTruth], binary: &Path) -> Result<PeerRun, String> {
    if !binary.is_file() {
        return Err(format!(
            "not built: no {} (build it with `cargo build --release` in dev/peers/opendefocus, or set {OPENDEFOCUS_ENV})",
            binary.display()
        ));
    }
    let dir = std::env::temp_dir().join(format!("lensblur-peer-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| format!("scratch folder {}: {e}", dir.display()))?;
    let result = run_in(truths, binary, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    result
}

fn run_in(truths: &[GroundTruth], binary: &Path, dir: &Path) -> Result<PeerRun, String> {
    let mut command = Command::new(binary);
    for (i, truth) in truths.iter().enumerate() {
        let (input, output) = (dir.join(format!("{i}.in")), dir.join(format!("{i}.out")));
        let mut file = std::fs::File::create(&input).map_err(|e| format!("{}: {e}", input.display()))?;
        file.write_all(&encode(truth)).map_err(|e| format!("{}: {e}", input.display()))?;
        command.arg(&input).arg(&output);
    }
    let done = command.output().map_err(|e| format!("could not start {}: {e}", binary.display()))?;
    if !done.status.success() {
        let stderr = String::from_utf8_lossy(&done.stderr);
        let last = stderr.lines().filter(|l| !l.contains("XDG_RUNTIME_DIR")).next_back().unwrap_or("").to_string();
        return Err(format!("the peer failed ({}): {last}", done.status));
    }
    let stdout = String::from_utf8_lossy(&done.stdout);
    let field = |prefix: &str| -> Vec<f64> {
        stdout.lines().filter_map(|l| l.strip_prefix(prefix)).filter_map(|l| l.rsplit(' ').next()?.parse().ok()).collect()
    };
    let (init, seconds) = (field("init "), field("frame "));
    if seconds.len() != truths.len() {
        return Err(format!("the peer reported {} of {} frames", seconds.len(), truths.len()));
    }
    let mut renders = Vec::new();
    for (i, (truth, s)) in truths.iter().zip(seconds).enumerate() {
        let path = dir.join(format!("{i}.out"));
        let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        renders.push((decode(&bytes, truth.pinhole.width, truth.pinhole.height)?, s));
    }
    Ok(PeerRun::Rendered { renders, init_seconds: init.first().copied().unwrap_or(0.0) })
}
