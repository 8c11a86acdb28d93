//! The Vulkan instance: loader entry, optional Khronos validation with a debug-utils messenger
//! (chained into instance creation so that is validated too), and physical-device discovery.
use std::ffi::CStr;

use ash::vk;

use super::error::VkCall;
use super::validation::{messenger_info, MessageLog};
use crate::{Error, Result};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

pub(crate) struct Instance {
    pub(crate) entry: ash::Entry,
    pub(crate) raw: ash::Instance,
    debug_utils: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    /// Boxed so the messenger's user-data pointer stays valid while the instance lives.
    pub(crate) log: Box<MessageLog>,
}

impl Instance {
    pub(crate) fn new(validation: bool) -> Result<Self> {
        // SAFETY: loading the system Vulkan loader library; no Vulkan call happens before it.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| {
            Error::NoVulkan(format!(
                "cannot load the Vulkan loader (libvulkan.so.1): {e}. Install a Vulkan driver, e.g. \
                 `apt-get install libvulkan1 mesa-vulkan-drivers` (lavapipe runs on any CPU)"
            ))
        })?;
        if validation {
            require_validation_layer(&entry)?;
            require_layer_extension(&entry, vk::EXT_VALIDATION_FEATURES_NAME)?;
        }
        let log = Box::<MessageLog>::default();
        let app = vk::ApplicationInfo::default()
            .application_name(c"lensblur")
            .engine_name(c"lensblur")
            .api_version(vk::API_VERSION_1_2);
        let layers = [VALIDATION_LAYER.as_ptr()];
        // VK_EXT_validation_features is the layer's own instance extension: the spec allows the
        // chained `ValidationFeaturesEXT` only with it enabled (layer 1.3.239 happens to honour
        // the struct without it; a stricter layer or loader need not).
        let extensions = [ash::ext::debug_utils::NAME.as_ptr(), vk::EXT_VALIDATION_FEATURES_NAME.as_ptr()];
        let mut messenger = messenger_info(&log);
        // Synchronization validation catches missing barriers, which lavapipe would forgive
        // (it runs one command at a time); a unit test in command.rs proves it reports them.
        let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
        let mut info = vk::InstanceCreateInfo::default().application_info(&app);
        if validation {
            info = info
                .enabled_layer_names(&layers)
                .enabled_extension_names(&extensions)
                .push_next(&mut messenger)
                .push_next(&mut features);
        }
        // SAFETY: every pointer in `info` refers to locals that outlive the call.
        let raw = unsafe { entry.create_instance(&info, None) }.map_err(|result| match result {
            vk::Result::ERROR_INCOMPATIBLE_DRIVER | vk::Result::ERROR_INITIALIZATION_FAILED => Error::NoVulkan(format!(
                "vkCreateInstance failed ({result:?}): no usable Vulkan driver. Install one, e.g. \
                 `apt-get install mesa-vulkan-drivers` (lavapipe)"
            )),
            result => Error::Vulkan { call: "vkCreateInstance", result },
        })?;
        let mut instance = Self { entry, raw, debug_utils: None, log };
        if validation {
            let loader = ash::ext::debug_utils::Instance::new(&instance.entry, &instance.raw);
            // SAFETY: the instance is alive and was created with VK_EXT_debug_utils enabled.
            let handle = unsafe { loader.create_debug_utils_messenger(&messenger_info(&instance.log), None) }
                .call("vkCreateDebugUtilsMessengerEXT")?;
            instance.debug_utils = Some((loader, handle));
        }
        instance.log.check()?;
        Ok(instance)
    }

    pub(crate) fn validation_enabled(&self) -> bool {
        self.debug_utils.is_some()
    }

    pub(crate) fn physical_devices(&self) -> Result<Vec<vk::PhysicalDevice>> {
        // SAFETY: the instance is alive.
        unsafe { self.raw.enumerate_physical_devices() }.call("vkEnumeratePhysicalDevices")
    }
}

fn require_validation_layer(entry: &ash::Entry) -> Result<()> {
    // SAFETY: a global query with no pointers from us.
    let layers = unsafe { entry.enumerate_instance_layer_properties() }.call("vkEnumerateInstanceLayerProperties")?;
    let found = layers.iter().any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == VALIDATION_LAYER));
    if found {
        Ok(())
    } else {
        Err(Error::NoVulkan(
            "LENSBLUR_VALIDATION=1 needs VK_LAYER_KHRONOS_validation: `apt-get install vulkan-validationlayers`".into(),
        ))
    }
}

/// Fails unless the validation layer provides `extension` (an instance extension of the layer,
/// not of the loader, so it is listed under the layer's name).
fn require_layer_extension(entry: &ash::Entry, extension: &CStr) -> Result<()> {
    // SAFETY: a global query; the layer name is a valid NUL-terminated string.
    let extensions = unsafe { entry.enumerate_instance_extension_properties(Some(VALIDATION_LAYER)) }
        .call("vkEnumerateInstanceExtensionProperties")?;
    if extensions.iter().any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == extension)) {
        return Ok(());
    }
    Err(Error::NoVulkan(format!(
        "LENSBLUR_VALIDATION=1 needs {} from VK_LAYER_KHRONOS_validation (synchronization validation); \
         install a newer vulkan-validationlayers",
        extension.to_string_lossy()
    )))
}

impl Drop for Instance {
    fn drop(&mut self) {
        // SAFETY: every device of this instance has been destroyed (each holds an Arc to it);
        // the messenger goes first, then the instance.
        unsafe {
            if let Some((loader, messenger)) = self.debug_utils.take() {
                loader.destroy_debug_utils_messenger(messenger, None);
            }
            self.raw.destroy_instance(None);
        }
        self.log.flush_unreported();
    }
}
