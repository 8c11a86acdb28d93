//! The Vulkan platform end to end: upload, dispatch, read back, validation, RAII teardown.
mod common;

use common::{finish, gpu, max_abs_diff, pattern};
use lensblur::image::Image;
use lensblur::render::disk::{disk_blur_cpu, DiskBlur, DiskKernel, DISK_BLUR_SLOTS};
use lensblur::vk::{Buffer, CommandBatch};

#[test]
fn gpu_disk_blur_matches_cpu_reference() {
    let ctx = gpu();
    let blur = DiskBlur::new(&ctx).unwrap();
    // Sizes that do not divide the 16x16 workgroup, radii from sub-pixel to large.
    for (w, h, r) in [(37, 23, 0.3), (64, 48, 3.5), (50, 41, 11.0)] {
        let image = pattern(w, h);
        let kernel = DiskKernel::new(r);
        let gpu_out = blur.run(&image, &kernel).unwrap();
        let cpu_out = disk_blur_cpu(&image, &kernel);
        // Same taps in the same order in f32; values up to ~20 (HDR) so allow 1e-5 relative.
        let tol = 2e-5 * 20.0;
        let diff = max_abs_diff(&gpu_out, &cpu_out);
        assert!(diff <= tol, "{w}x{h} r={r}: max |gpu - cpu| = {diff} > {tol}");
    }
    drop(blur);
    finish(ctx);
}

#[test]
fn buffers_round_trip_and_zero_fill() {
    let ctx = gpu();
    let data: Vec<f32> = (0..1000).map(|i| i as f32 * 0.5 - 7.0).collect();
    let buffer = Buffer::from_slice(&ctx, "round trip", &data).unwrap();
    assert_eq!(buffer.read::<f32>(&ctx).unwrap(), data);
    let zero = Buffer::zeroed(&ctx, "zeros", 4096).unwrap();
    assert!(zero.read::<u32>(&ctx).unwrap().iter().all(|&v| v == 0));
    let mut batch = CommandBatch::new(&ctx).unwrap();
    batch.copy(&buffer, &zero, 4000).unwrap();
    batch.submit_and_wait().unwrap();
    assert_eq!(&zero.read::<f32>(&ctx).unwrap()[..1000], &data[..]);
    drop((buffer, zero, batch));
    finish(ctx);
}

#[test]
fn buffers_recorded_into_a_batch_are_uploaded_zeroed_and_read_back_by_its_one_submission() {
    let ctx = gpu();
    let data: Vec<[f32; 4]> = (0..300).map(|i| [i as f32, -0.5 * i as f32, 1e6, 0.25]).collect();
    let mut batch = CommandBatch::new(&ctx).unwrap();
    let source = Buffer::from_iter_in(&ctx, &mut batch, "source", data.len(), data.iter().copied()).unwrap();
    // Garbage first, so the recorded zero fill is what makes it zero.
    let target = Buffer::from_iter_in(&ctx, &mut batch, "target", 600, (0..600).map(|i| i as f32 + 1.0)).unwrap();
    let zeroed = Buffer::zeroed_in(&ctx, &mut batch, "zeroed", target.size()).unwrap();
    batch.copy(&zeroed, &target, 2000).unwrap();
    batch.copy(&source, &target, 1600).unwrap();
    let readable = target.readable_in(&mut batch).unwrap();
    batch.submit_and_wait().unwrap();
    let got: Vec<f32> = readable.read(&ctx).unwrap();
    let want: Vec<f32> = data
        .iter()
        .flatten()
        .copied()
        .take(400)
        .chain(std::iter::repeat(0.0).take(100))
        .chain((500..600).map(|i| i as f32 + 1.0))
        .collect();
    assert_eq!(got, want, "copies ran in recording order after the upload and the zero fill");
    let short = Buffer::from_iter_in(&ctx, &mut batch, "short", 10, [1.0f32; 4]);
    assert!(short.is_err(), "fewer items than declared is refused");
    drop((source, target, zeroed, readable, batch));
    finish(ctx);
}

#[test]
fn a_batch_reused_with_more_sets_than_one_pool_holds_stays_valid_and_deterministic() {
    // 70 dispatches need two descriptor pools; the batch is submitted and reused three times,
    // resetting the same two pools each time instead of creating new ones.
    let ctx = gpu();
    let pipeline = lensblur::vk::ComputePipeline::with_slots(&ctx, &lensblur::shaders::DISK_BLUR, &DISK_BLUR_SLOTS, 16).unwrap();
    let image = pattern(20, 20);
    let kernel = DiskKernel::new(2.0);
    let source = Buffer::from_slice(&ctx, "source", &image.pixels).unwrap();
    let weights = Buffer::from_slice(&ctx, "kernel", &kernel.weights).unwrap();
    let result = Buffer::zeroed(&ctx, "result", source.size()).unwrap();
    let push = [20i32, 20, kernel.half_extent as i32, 0];
    let expected = disk_blur_cpu(&image, &kernel);
    let mut batch = CommandBatch::new(&ctx).unwrap();
    for _ in 0..3 {
        for _ in 0..70 {
            batch
                .dispatch(
                    &pipeline,
                    &[source.all(), weights.all(), result.all()],
                    &push,
                    pipeline.groups_for([20, 20, 1]),
                )
                .unwrap();
        }
        assert_eq!(batch.len(), 70);
        batch.submit_and_wait().unwrap();
        assert!(batch.is_empty());
        assert_eq!(batch.descriptor_pool_count(), 2, "pools are reset and reused, not recreated");
        let pixels: Vec<[f32; 4]> = result.read(&ctx).unwrap();
        let out = Image { width: 20, height: 20, pixels };
        assert!(max_abs_diff(&out, &expected) < 4e-4, "HDR values ~20, f32 sums: 2e-5 relative");
    }
    drop((pipeline, source, weights, result, batch));
    finish(ctx);
}

/// A shot's frames each make their renderer anew; the context hands them the pipelines it
/// made for the first frame instead of creating them again (issue 24: start-up paid once).
#[test]
fn a_context_makes_each_pipeline_once_and_keeps_it_for_later_renders() {
    use lensblur::vk::ComputePipeline;
    let ctx = gpu();
    let first = ComputePipeline::with_slots(&ctx, &lensblur::shaders::DISK_BLUR, &DISK_BLUR_SLOTS, 16).unwrap();
    drop(first.clone());
    let again = ComputePipeline::with_slots(&ctx.clone(), &lensblur::shaders::DISK_BLUR, &DISK_BLUR_SLOTS, 16).unwrap();
    assert!(again.is_same(&first), "the same shader, slots and push size give the kept pipeline");
    let other_push = ComputePipeline::with_slots(&ctx, &lensblur::shaders::DISK_BLUR, &DISK_BLUR_SLOTS, 32).unwrap();
    assert!(!other_push.is_same(&first), "a different push-constant size is another pipeline");
    let specialized = ComputePipeline::specialized(&ctx, &lensblur::shaders::DISK_BLUR, &DISK_BLUR_SLOTS, 16, &[]).unwrap();
    assert!(specialized.is_same(&first), "no constants is the plain pipeline");
    drop((first, again, other_push, specialized));
    finish(ctx);
}

#[test]
fn validation_messages_fail_the_command() {
    // A storage-buffer offset of 4 bytes (the result, binding 2) violates
    // minStorageBufferOffsetAlignment (16 or more on every device we know), which only the
    // validation layer notices.
    let ctx = gpu();
    assert!(ctx.validation_enabled());
    let pipeline = lensblur::vk::ComputePipeline::with_slots(&ctx, &lensblur::shaders::DISK_BLUR, &DISK_BLUR_SLOTS, 16).unwrap();
    let buffer = Buffer::zeroed(&ctx, "misaligned", 1024).unwrap();
    let mut batch = CommandBatch::new(&ctx).unwrap();
    let misaligned = buffer.range(4, 512);
    let outcome = batch
        .dispatch(&pipeline, &[buffer.range(512, 512), buffer.all(), misaligned], &[0i32, 0, 0, 0], [1, 1, 1])
        .and_then(|()| batch.submit_and_wait());
    let err = outcome.expect_err("a misaligned binding must be reported");
    assert!(err.to_string().contains("alidation"), "{err}");
    drop((pipeline, buffer, batch));
    let _ = ctx.finish();
}

#[test]
fn dispatch_refuses_wrong_binding_count() {
    let ctx = gpu();
    let pipeline = lensblur::vk::ComputePipeline::with_slots(&ctx, &lensblur::shaders::DISK_BLUR, &DISK_BLUR_SLOTS, 16).unwrap();
    let buffer = Buffer::zeroed(&ctx, "one", 64).unwrap();
    let mut batch = CommandBatch::new(&ctx).unwrap();
    let err = batch.dispatch(&pipeline, &[buffer.all()], &[0i32; 4], [1, 1, 1]).unwrap_err();
    assert!(err.to_string().contains("1 buffers bound, pipeline declares 3"), "{err}");
    let err = batch.dispatch(&pipeline, &[buffer.all(); 3], &[0i32; 2], [1, 1, 1]).unwrap_err();
    assert!(err.to_string().contains("push constants"), "{err}");
    drop((pipeline, buffer, batch));
    finish(ctx);
}

#[test]
fn texel_bindings_are_checked_against_the_shader_and_the_device_limits() {
    use lensblur::render::drbokeh::DrBokehPush;
    use lensblur::vk::{ComputePipeline, Slot, TexelFormat};
    let ctx = gpu();
    let info = ctx.info().clone();
    // Every device here (lavapipe: 16 bytes) aligns texel views to 4 bytes or more.
    let alignment = info.min_texel_buffer_offset_alignment;
    assert!(alignment >= 4, "offset alignment {alignment}: the misaligned case below needs one of at least 4");
    let (vec4, float) = (Slot::Texels(TexelFormat::Vec4), Slot::Texels(TexelFormat::Float));
    let slots = [vec4, float, float, Slot::Storage, Slot::Storage];
    let push = std::mem::size_of::<DrBokehPush>();
    // Binding kinds come from the SPIR-V: a pipeline that declares another kind is refused.
    let shader = &lensblur::shaders::DRBOKEH_LAYER_SOURCES;
    let err = ComputePipeline::new(&ctx, shader, 5, push).err().expect("storage slots for texel bindings");
    assert!(err.to_string().contains("binding 0 is a texel buffer in the shader"), "{err}");
    let err = ComputePipeline::with_slots(&ctx, shader, &slots[..4], push).err().expect("a binding left out");
    assert!(err.to_string().contains("binding 4 is a storage buffer in the shader"), "{err}");
    let pipeline = ComputePipeline::with_slots(&ctx, shader, &slots, push).unwrap();
    let buffer = Buffer::zeroed(&ctx, "texels", 4096).unwrap();
    let misaligned = buffer.range(alignment / 2, 1024);
    let bindings = [misaligned, buffer.all(), buffer.all(), buffer.all(), buffer.all()];
    let mut batch = CommandBatch::new(&ctx).unwrap();
    let zero: DrBokehPush = bytemuck::Zeroable::zeroed();
    let err = batch.dispatch(&pipeline, &bindings, &zero, [1, 1, 1]).unwrap_err();
    assert!(err.to_string().contains("offset alignment"), "{err}");
    // A partial trailing texel is left out of the view; aligned bindings record and run.
    let bindings = [buffer.range(0, 1030), buffer.all(), buffer.all(), buffer.all(), buffer.all()];
    batch.dispatch(&pipeline, &bindings, &zero, [1, 1, 1]).unwrap();
    batch.submit_and_wait().unwrap();
    drop((pipeline, buffer, batch));
    finish(ctx);
}

#[test]
fn memory_budget_is_within_the_heap_and_measured_for_a_cpu_device() {
    let ctx = gpu();
    let info = ctx.info().clone();
    let budget = ctx.memory_budget();
    assert!(budget.available_bytes > 0 && budget.available_bytes <= info.device_local_bytes, "{budget:?} vs {info:?}");
    if !info.memory_budget_extension {
        if info.kind == "CPU" {
            // System memory: the heap less what this context holds, at most MemAvailable.
            let held = ctx.allocated_bytes();
            assert!(budget.measured && budget.available_bytes <= info.device_local_bytes - held, "{budget:?}");
            let _buffer = lensblur::vk::Buffer::uninitialised(&ctx, "budget test", 64 << 20).unwrap();
            let after = ctx.memory_budget();
            assert!(
                after.available_bytes + (64 << 20) <= budget.available_bytes + (16 << 20),
                "a 64 MiB buffer is counted: {budget:?} then {after:?}"
            );
        } else {
            assert!(!budget.measured && budget.available_bytes == info.device_local_bytes, "no extension: the heap size");
        }
    }
    finish(ctx);
}

#[test]
fn shader_workgroup_size_is_read_from_spirv() {
    assert_eq!(lensblur::shaders::DISK_BLUR.local_size, [16, 16, 1]);
    let _ = Image::new(1, 1);
}

/// Opens the validated device with its pipeline cache in `dir`.
fn gpu_with_pipeline_cache(dir: &std::path::Path) -> lensblur::vk::Context {
    let options = lensblur::vk::ContextOptions {
        validation: true,
        pipeline_cache: Some(dir.to_owned()),
        ..lensblur::vk::ContextOptions::from_env()
    };
    lensblur::vk::Context::new(&options).expect("GPU tests need a Vulkan device with validation layers (see README)")
}

fn blur_once(ctx: &lensblur::vk::Context) -> Image {
    let blur = DiskBlur::new(ctx).unwrap();
    blur.run(&pattern(40, 30), &DiskKernel::new(4.5)).unwrap()
}

#[test]
fn compiled_pipelines_are_saved_on_close_and_reloaded_by_the_next_process() {
    let dir = common::temp_dir("vk_platform", "pipeline_cache_round_trip");
    let first = gpu_with_pipeline_cache(&dir);
    let file = first.pipeline_cache_file().expect("a cache folder was given").to_owned();
    assert!(file.starts_with(&dir), "{} is not inside {}", file.display(), dir.display());
    assert_eq!(first.pipeline_cache_loaded_bytes(), 0, "an empty folder has nothing to load");
    let expected = blur_once(&first);
    finish(first);
    let saved = std::fs::read(&file).expect("closing the device writes the cache file");
    assert!(saved.len() >= 32, "a cache file holds at least the 32-byte Vulkan header");
    let leftovers: Vec<_> =
        std::fs::read_dir(&dir).unwrap().filter_map(|e| e.ok()).filter(|e| e.path() != file).collect();
    assert!(leftovers.is_empty(), "temporary files left behind: {leftovers:?}");

    let second = gpu_with_pipeline_cache(&dir);
    assert_eq!(second.pipeline_cache_loaded_bytes(), saved.len(), "the saved cache is accepted whole");
    assert_eq!(blur_once(&second).pixels, expected.pixels, "a cached pipeline computes the same bits");
    finish(second);
}

#[test]
fn a_corrupt_or_foreign_cache_file_is_ignored_and_replaced() {
    let dir = common::temp_dir("vk_platform", "pipeline_cache_foreign");
    let probe = gpu_with_pipeline_cache(&dir);
    let file = probe.pipeline_cache_file().unwrap().to_owned();
    let expected = blur_once(&probe);
    finish(probe);
    let valid = std::fs::read(&file).unwrap();
    let mut foreign_uuid = valid.clone();
    foreign_uuid[20] ^= 0xff;
    let mut garbage = vec![0xA5u8; 4096];
    garbage[..4].copy_from_slice(&32u32.to_le_bytes());
    for (what, bytes) in
        [("another driver build's cache", foreign_uuid), ("garbage", garbage), ("an empty file", Vec::new())]
    {
        std::fs::write(&file, &bytes).unwrap();
        let ctx = gpu_with_pipeline_cache(&dir);
        assert_eq!(ctx.pipeline_cache_loaded_bytes(), 0, "{what} must not reach the driver");
        assert_eq!(blur_once(&ctx).pixels, expected.pixels, "{what}: same result without the cache");
        finish(ctx);
        let rewritten = std::fs::read(&file).unwrap();
        assert_eq!(&rewritten[..32], &valid[..32], "{what} is replaced by this device's cache");
    }
}
