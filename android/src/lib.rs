//! The Android sample: a NativeActivity (`android-activity`) that embeds tilegraph the way a
//! game engine does. It creates its own Vulkan instance with `VK_KHR_android_surface`, a
//! surface on the activity's `ANativeWindow`, a device with what tilegraph asks for plus
//! `VK_KHR_swapchain`, and a swapchain; tilegraph adopts the device and records each frame —
//! the city (or a scene named by `debug.tilegraph.scene`) along its camera path — into the
//! sample's command buffer and swapchain image, which the sample submits and presents. A touch
//! switches the culling technique; once a second a line with the frame rate and each pass's
//! GPU time goes to the log (`adb logcat -s tilegraph`).
//!
//! Android-only code is compiled for `target_os = "android"` (`cargo xtask test` checks it for
//! aarch64-linux-android); on other targets only the platform-independent part (`report.rs`)
//! is built and tested. docs/ANDROID.md builds the APK.

pub mod report;

#[cfg(target_os = "android")]
mod app;
#[cfg(target_os = "android")]
mod vulkan;

/// Entry point NativeActivity's glue calls on the activity's thread.
#[cfg(target_os = "android")]
#[no_mangle]
fn android_main(app: android_activity::AndroidApp) {
    app::run(app);
}
