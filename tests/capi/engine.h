/*
 * A C "engine" for the C ABI's tests: what an engine written in C does before and around
 * tilegraph — its own instance with the validation layer, synchronization validation and a
 * debug messenger that counts every warning and error; its own device, created with what
 * tilegraph asks for; its own image, command buffers and fences. Plain Vulkan, no tilegraph
 * internals. Header-only: each test program includes it once.
 */
#ifndef TILEGRAPH_TEST_ENGINE_H
#define TILEGRAPH_TEST_ENGINE_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <vulkan/vulkan.h>

#include "check.h"
#include "tilegraph.h"

typedef struct Engine {
    VkInstance instance;
    VkDebugUtilsMessengerEXT messenger;
    VkPhysicalDevice physical;
    uint32_t family;
    VkDevice device;
    VkQueue queue;
    VkCommandPool pool;
    uint32_t requirements_features; /* TgFeature bits the device was created with */
} Engine;

/* Every warning and error the layer reported (loader messages about the machine excluded). */
static int engine_messages = 0;

static VKAPI_ATTR VkBool32 VKAPI_CALL engine_messenger(
    VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT types,
    const VkDebugUtilsMessengerCallbackDataEXT *data, void *user) {
    (void)user;
    if (types == VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT) {
        return VK_FALSE;
    }
    if (severity & (VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT |
                    VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT)) {
        engine_messages++;
        fprintf(stderr, "validation: %s\n", data->pMessage);
    }
    return VK_FALSE;
}

/* Instance (validation + synchronization validation + messenger) and the first device with a
 * graphics + compute queue. */
static void engine_start(Engine *e) {
    memset(e, 0, sizeof *e);
    VkApplicationInfo app = {.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO,
                             .pApplicationName = "c-engine",
                             .apiVersion = VK_API_VERSION_1_3};
    const char *layers[] = {"VK_LAYER_KHRONOS_validation"};
    const char *extensions[] = {VK_EXT_DEBUG_UTILS_EXTENSION_NAME,
                                VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME};
    VkValidationFeatureEnableEXT enables[] = {
        VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT};
    VkValidationFeaturesEXT features = {.sType = VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT,
                                        .enabledValidationFeatureCount = 1,
                                        .pEnabledValidationFeatures = enables};
    VkDebugUtilsMessengerCreateInfoEXT messenger = {
        .sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT,
        .pNext = &features,
        .messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT |
                           VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT,
        .messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                       VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                       VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT,
        .pfnUserCallback = engine_messenger};
    VkInstanceCreateInfo info = {.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO,
                                 .pNext = &messenger, /* instance creation is watched too */
                                 .pApplicationInfo = &app,
                                 .enabledLayerCount = 1,
                                 .ppEnabledLayerNames = layers,
                                 .enabledExtensionCount = 2,
                                 .ppEnabledExtensionNames = extensions};
    VK_CHECK(vkCreateInstance(&info, NULL, &e->instance));
    PFN_vkCreateDebugUtilsMessengerEXT create_messenger =
        (PFN_vkCreateDebugUtilsMessengerEXT)vkGetInstanceProcAddr(
            e->instance, "vkCreateDebugUtilsMessengerEXT");
    CHECK(create_messenger != NULL, "no vkCreateDebugUtilsMessengerEXT");
    messenger.pNext = NULL;
    VK_CHECK(create_messenger(e->instance, &messenger, NULL, &e->messenger));

    uint32_t count = 1;
    VkResult r = vkEnumeratePhysicalDevices(e->instance, &count, &e->physical);
    CHECK((r == VK_SUCCESS || r == VK_INCOMPLETE) && count == 1, "no physical device");
    VkQueueFamilyProperties families[16];
    uint32_t family_count = 16;
    vkGetPhysicalDeviceQueueFamilyProperties(e->physical, &family_count, families);
    e->family = UINT32_MAX;
    for (uint32_t i = 0; i < family_count; i++) {
        VkQueueFlags want = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
        if ((families[i].queueFlags & want) == want) {
            e->family = i;
            break;
        }
    }
    CHECK(e->family != UINT32_MAX, "no graphics + compute queue family");
}

static TgGetInstanceProcAddr engine_gipa(void) {
    return (TgGetInstanceProcAddr)vkGetInstanceProcAddr;
}

/* What tilegraph needs on this device for `technique` with `culling`. */
static TgDeviceRequirements engine_requirements(const Engine *e, uint32_t technique,
                                                uint32_t culling) {
    TgDeviceQuery query = {.get_instance_proc_addr = engine_gipa(),
                           .instance = e->instance,
                           .physical_device = e->physical,
                           .queue_family = e->family,
                           .technique = technique,
                           .culling = culling};
    TgDeviceRequirements req;
    TG_CHECK(tg_device_requirements(&query, &req));
    return req;
}

/* The features (TgFeature bits) tilegraph needs for `technique` with `culling`: an engine
 * whose frames have several views enables the union of theirs. */
static inline uint32_t engine_features(const Engine *e, uint32_t technique, uint32_t culling) {
    return engine_requirements(e, technique, culling).features;
}

/* Asks tilegraph what `technique` and `culling` need, sets those features in the engine's own
 * feature structs (the engine could set its own there too), enables the extensions, and
 * creates the device. `features_override` non-zero: the device gets only those TgFeature bits
 * instead (a device that lacks what tilegraph would ask for). */
static void engine_create_device(Engine *e, uint32_t technique, uint32_t culling,
                                 uint32_t features_override) {
    TgDeviceRequirements req = engine_requirements(e, technique, culling);
    if (features_override != 0) {
        req.features = features_override;
    }
    VkPhysicalDeviceConditionalRenderingFeaturesEXT conditional = {
        .sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_CONDITIONAL_RENDERING_FEATURES_EXT};
    VkPhysicalDeviceVulkan13Features v13 = {
        .sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES, .pNext = &conditional};
    VkPhysicalDeviceVulkan12Features v12 = {
        .sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES, .pNext = &v13};
    VkPhysicalDeviceVulkan11Features v11 = {
        .sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES, .pNext = &v12};
    VkPhysicalDeviceFeatures2 features2 = {.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2,
                                           .pNext = &v11};
    CHECK(req.vulkan13, "this engine expects a Vulkan 1.3 device");
    TgFeatureStructs structs = {.features2 = &features2,
                                .vulkan11 = &v11,
                                .vulkan12 = &v12,
                                .vulkan13 = &v13,
                                .conditional_rendering = &conditional};
    TG_CHECK(tg_enable_features(&req, &structs));
    if (!(req.features & TG_FEATURE_CONDITIONAL_RENDERING)) {
        v13.pNext = NULL; /* the extension's struct only with the extension */
    }
    float priority = 1.0f;
    VkDeviceQueueCreateInfo queue = {.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
                                     .queueFamilyIndex = e->family,
                                     .queueCount = 1,
                                     .pQueuePriorities = &priority};
    VkDeviceCreateInfo info = {.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
                               .pNext = &features2,
                               .queueCreateInfoCount = 1,
                               .pQueueCreateInfos = &queue,
                               .enabledExtensionCount = req.extension_count,
                               .ppEnabledExtensionNames = req.extensions};
    VK_CHECK(vkCreateDevice(e->physical, &info, NULL, &e->device));
    vkGetDeviceQueue(e->device, e->family, 0, &e->queue);
    VkCommandPoolCreateInfo pool = {.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
                                    .flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT,
                                    .queueFamilyIndex = e->family};
    VK_CHECK(vkCreateCommandPool(e->device, &pool, NULL, &e->pool));
    e->requirements_features = req.features;
}

/* Hands the device to tilegraph with `profile` forced (or NULL: the device's own). */
static TgStatus engine_adopt(const Engine *e, const char *profile, TgContext *context) {
    TgAdoptInfo info = {.get_instance_proc_addr = engine_gipa(),
                        .instance = e->instance,
                        .instance_has_debug_utils = 1,
                        .physical_device = e->physical,
                        .device = e->device,
                        .queue_family = e->family,
                        .queue_index = 0,
                        .enabled_features = e->requirements_features,
                        .profile = profile};
    return tg_context_adopt(&info, context);
}

/* An image the engine owns, with its memory and view. */
typedef struct EngineImage {
    VkImage image;
    VkDeviceMemory memory;
    VkImageView view;
} EngineImage;

static uint32_t engine_memory_type(const Engine *e, uint32_t bits, VkMemoryPropertyFlags want) {
    VkPhysicalDeviceMemoryProperties props;
    vkGetPhysicalDeviceMemoryProperties(e->physical, &props);
    for (uint32_t i = 0; i < props.memoryTypeCount; i++) {
        if ((bits & (1u << i)) && (props.memoryTypes[i].propertyFlags & want) == want) {
            return i;
        }
    }
    CHECK(0, "no memory type for bits %#x", bits);
    return 0;
}

static EngineImage engine_image(const Engine *e, uint32_t width, uint32_t height) {
    EngineImage img;
    VkImageCreateInfo info = {
        .sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
        .imageType = VK_IMAGE_TYPE_2D,
        .format = VK_FORMAT_R8G8B8A8_UNORM,
        .extent = {width, height, 1},
        .mipLevels = 1,
        .arrayLayers = 1,
        .samples = VK_SAMPLE_COUNT_1_BIT,
        .tiling = VK_IMAGE_TILING_OPTIMAL,
        .usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
        .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED};
    VK_CHECK(vkCreateImage(e->device, &info, NULL, &img.image));
    VkMemoryRequirements req;
    vkGetImageMemoryRequirements(e->device, img.image, &req);
    VkMemoryAllocateInfo alloc = {
        .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
        .allocationSize = req.size,
        .memoryTypeIndex =
            engine_memory_type(e, req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT)};
    VK_CHECK(vkAllocateMemory(e->device, &alloc, NULL, &img.memory));
    VK_CHECK(vkBindImageMemory(e->device, img.image, img.memory, 0));
    VkImageViewCreateInfo view = {
        .sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
        .image = img.image,
        .viewType = VK_IMAGE_VIEW_TYPE_2D,
        .format = VK_FORMAT_R8G8B8A8_UNORM,
        .subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1}};
    VK_CHECK(vkCreateImageView(e->device, &view, NULL, &img.view));
    return img;
}

static void engine_image_destroy(const Engine *e, EngineImage *img) {
    vkDestroyImageView(e->device, img->view, NULL);
    vkDestroyImage(e->device, img->image, NULL);
    vkFreeMemory(e->device, img->memory, NULL);
}

/* The target description of `img` for tilegraph, found in `initial_layout` (after the engine's
 * last use at `stages`/`access`) and left for a copy. */
static TgTarget engine_target(const EngineImage *img, uint32_t width, uint32_t height,
                              VkImageLayout initial_layout, VkPipelineStageFlags2 stages,
                              VkAccessFlags2 access) {
    TgTarget t = {.image = (uint64_t)img->image,
                  .view = (uint64_t)img->view,
                  .format = VK_FORMAT_R8G8B8A8_UNORM,
                  .width = width,
                  .height = height,
                  .initial = {initial_layout, stages, access},
                  .final_state = {VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                                  VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_READ_BIT}};
    return t;
}

/* The target of a frame in a loop that copies the image out after each: the first frame finds
 * it undefined, the later ones where the last left it (after its copy). */
static TgTarget engine_frame_target(const EngineImage *img, uint32_t width, uint32_t height,
                                    int first) {
    return first ? engine_target(img, width, height, VK_IMAGE_LAYOUT_UNDEFINED,
                                 VK_PIPELINE_STAGE_2_NONE, VK_ACCESS_2_NONE)
                 : engine_target(img, width, height, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                                 VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_READ_BIT);
}

/* One engine frame slot: a command buffer and its fence. */
typedef struct EngineSlot {
    VkCommandBuffer cb;
    VkFence fence;
    int submitted;
} EngineSlot;

static EngineSlot engine_slot(const Engine *e) {
    EngineSlot s = {0};
    VkCommandBufferAllocateInfo alloc = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
                                         .commandPool = e->pool,
                                         .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
                                         .commandBufferCount = 1};
    VK_CHECK(vkAllocateCommandBuffers(e->device, &alloc, &s.cb));
    VkFenceCreateInfo fence = {.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VK_CHECK(vkCreateFence(e->device, &fence, NULL, &s.fence));
    return s;
}

/* Waits for the slot's last frame and begins its command buffer. */
static void engine_begin(const Engine *e, EngineSlot *s) {
    if (s->submitted) {
        VK_CHECK(vkWaitForFences(e->device, 1, &s->fence, VK_TRUE, UINT64_MAX));
        VK_CHECK(vkResetFences(e->device, 1, &s->fence));
        s->submitted = 0;
    }
    VK_CHECK(vkResetCommandBuffer(s->cb, 0));
    VkCommandBufferBeginInfo begin = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    VK_CHECK(vkBeginCommandBuffer(s->cb, &begin));
}

static void engine_submit(const Engine *e, EngineSlot *s) {
    VK_CHECK(vkEndCommandBuffer(s->cb));
    VkSubmitInfo submit = {.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO,
                           .commandBufferCount = 1,
                           .pCommandBuffers = &s->cb};
    VK_CHECK(vkQueueSubmit(e->queue, 1, &submit, s->fence));
    s->submitted = 1;
}

static void engine_slot_destroy(const Engine *e, EngineSlot *s) {
    vkDestroyFence(e->device, s->fence, NULL);
    vkFreeCommandBuffers(e->device, e->pool, 1, &s->cb);
}

/* Destroys the device (the layer reports any object still alive on it), the messenger and
 * the instance; returns the number of validation messages over the whole run. */
static int engine_destroy(Engine *e) {
    if (e->device != VK_NULL_HANDLE) {
        VK_CHECK(vkDeviceWaitIdle(e->device));
        vkDestroyCommandPool(e->device, e->pool, NULL);
        vkDestroyDevice(e->device, NULL);
    }
    PFN_vkDestroyDebugUtilsMessengerEXT destroy_messenger =
        (PFN_vkDestroyDebugUtilsMessengerEXT)vkGetInstanceProcAddr(
            e->instance, "vkDestroyDebugUtilsMessengerEXT");
    destroy_messenger(e->instance, e->messenger, NULL);
    vkDestroyInstance(e->instance, NULL);
    return engine_messages;
}

/* Copies the image (left in TRANSFER_SRC by tilegraph) into the file at `path` (raw RGBA8). */
static inline void engine_read_back(const Engine *e, const EngineImage *img, uint32_t width,
                                    uint32_t height, const char *path) {
    VkDeviceSize size = (VkDeviceSize)width * height * 4;
    VkBufferCreateInfo info = {.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                               .size = size,
                               .usage = VK_BUFFER_USAGE_TRANSFER_DST_BIT};
    VkBuffer buffer;
    VK_CHECK(vkCreateBuffer(e->device, &info, NULL, &buffer));
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(e->device, buffer, &req);
    VkMemoryAllocateInfo alloc = {
        .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
        .allocationSize = req.size,
        .memoryTypeIndex = engine_memory_type(e, req.memoryTypeBits,
                                              VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
                                                  VK_MEMORY_PROPERTY_HOST_COHERENT_BIT)};
    VkDeviceMemory memory;
    VK_CHECK(vkAllocateMemory(e->device, &alloc, NULL, &memory));
    VK_CHECK(vkBindBufferMemory(e->device, buffer, memory, 0));

    EngineSlot s = engine_slot(e);
    engine_begin(e, &s);
    VkBufferImageCopy region = {.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
                                .imageExtent = {width, height, 1}};
    vkCmdCopyImageToBuffer(s.cb, img->image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, buffer, 1,
                           &region);
    VkMemoryBarrier2 to_host = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER_2,
                                .srcStageMask = VK_PIPELINE_STAGE_2_COPY_BIT,
                                .srcAccessMask = VK_ACCESS_2_TRANSFER_WRITE_BIT,
                                .dstStageMask = VK_PIPELINE_STAGE_2_HOST_BIT,
                                .dstAccessMask = VK_ACCESS_2_HOST_READ_BIT};
    VkDependencyInfo dep = {.sType = VK_STRUCTURE_TYPE_DEPENDENCY_INFO,
                            .memoryBarrierCount = 1,
                            .pMemoryBarriers = &to_host};
    vkCmdPipelineBarrier2(s.cb, &dep);
    engine_submit(e, &s);
    VK_CHECK(vkWaitForFences(e->device, 1, &s.fence, VK_TRUE, UINT64_MAX));

    void *pixels;
    VK_CHECK(vkMapMemory(e->device, memory, 0, size, 0, &pixels));
    FILE *f = fopen(path, "wb");
    CHECK(f != NULL, "cannot write %s", path);
    CHECK(fwrite(pixels, 1, (size_t)size, f) == (size_t)size, "short write to %s", path);
    fclose(f);
    vkUnmapMemory(e->device, memory);
    engine_slot_destroy(e, &s);
    vkDestroyBuffer(e->device, buffer, NULL);
    vkFreeMemory(e->device, memory, NULL);
}


#endif
