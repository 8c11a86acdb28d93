//! Vulkan plumbing on raw `ash`: the only module with Vulkan calls and `unsafe`.
