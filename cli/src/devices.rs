//! `lensblur devices`: the Vulkan devices this machine has, and the one lensblur would use.
use lensblur::vk::{list_devices, ContextOptions};

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur devices                    every Vulkan device, the one in use marked\n  lensblur devices --json             the same as JSON\n  LENSBLUR_DEVICE=1 lensblur devices  pick a device by index or name substring (every command)")]
pub struct Args {
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (devices, chosen) = list_devices(&ContextOptions::from_env())?;
    if args.json {
        let report = serde_json::json!({ "devices": devices, "chosen": chosen });
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    if devices.is_empty() {
        anyhow::bail!("no Vulkan devices found; install a driver (e.g. `apt-get install mesa-vulkan-drivers`)");
    }
    for d in &devices {
        let mark = if Some(d.index) == chosen { "*" } else { " " };
        println!("{mark} {}: {} [{}]", d.index, d.name, d.kind);
        println!("      driver: {}, Vulkan {}", d.driver, d.api_version);
        println!(
            "      memory: {:.1} GiB device-local, max allocation {:.1} GiB; tiles planned from {}",
            d.device_local_bytes as f64 / (1u64 << 30) as f64,
            d.max_allocation_bytes as f64 / (1u64 << 30) as f64,
            if d.memory_budget_extension { "the driver's budget (VK_EXT_memory_budget)" } else { "the heap size" }
        );
        println!(
            "      workgroup: {} invocations max, size {:?}, subgroup {}; storage buffer range {} MiB; push constants {} B; shared memory {} KiB",
            d.max_workgroup_invocations,
            d.max_workgroup_size,
            d.subgroup_size,
            d.max_storage_buffer_range >> 20,
            d.max_push_constants_size,
            d.max_shared_memory_bytes >> 10
        );
        match d.timestamp_period_ns {
            Some(p) => println!("      timestamps: {p} ns per tick"),
            None => println!("      timestamps: not supported on the compute queue"),
        }
    }
    match chosen {
        Some(i) => println!("* = the device lensblur uses (override with LENSBLUR_DEVICE=<index|name>); chosen: {i}"),
        None => println!("no device matches LENSBLUR_DEVICE; lensblur would fail to start"),
    }
    Ok(())
}
