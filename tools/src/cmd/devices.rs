//! `fabric devices`: the Vulkan devices and the one `fabric render` would choose.

use anyhow::{Context, Result};
use clap::Args;
use fabric_runtime::vk::{Device, DeviceOptions, Instance, InstanceOptions, enumerate_devices};

#[derive(Args, Debug)]
pub struct DevicesArgs {
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Device name (substring) to choose, as `--device` elsewhere; default: FABRIC_DEVICE or automatic.
    #[arg(long)]
    pub device: Option<String>,
}

pub fn run(args: DevicesArgs) -> Result<()> {
    let instance = Instance::new(&InstanceOptions { validation: Some(false), ..Default::default() }).context("cannot start Vulkan")?;
    let devices = enumerate_devices(&instance).context("cannot list Vulkan devices")?;
    drop(instance);
    let chosen = Device::new(&DeviceOptions { name: args.device.clone(), instance: InstanceOptions { validation: Some(false), ..Default::default() }, ..Default::default() })
        .map(|d| d.info().name.clone());
    if args.json {
        let v = serde_json::json!({ "devices": devices, "chosen": chosen.as_ref().ok(), "error": chosen.as_ref().err().map(|e| e.to_string()) });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        for d in &devices {
            let mark = if chosen.as_ref().ok() == Some(&d.name) { "*" } else { " " };
            let usable = match &d.usable {
                Ok(()) => "usable".to_string(),
                Err(e) => format!("unusable: {e}"),
            };
            println!(
                "{mark} {} ({}, Vulkan {}, driver {}), timestamps {} bits @ {} ns, max storage buffer {} MiB, {usable}",
                d.name,
                d.kind,
                d.api_version,
                d.driver,
                d.timestamp_valid_bits,
                d.timestamp_period_ns,
                d.max_storage_buffer_range >> 20
            );
        }
    }
    chosen.map(|_| ()).context("no device can be used")
}
