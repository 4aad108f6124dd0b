/*
 * An engine's own material in C: its vertex and fragment shaders (tests/capi's caller passes
 * shaders/spv/test_engine.{vert,frag}.spv, compiled against shaders/include/
 * tilegraph_instance.glsl), its pipeline layout (tilegraph's scene set, then a set of its own
 * holding a tint uniform) and a bind callback that binds that set. The city's opaque materials
 * are given to it; five frames of the city's path are rendered through tilegraph's culling
 * (`none`, `hiz-2phase`) — or, for the comparison, by a renderer with no engine material
 * registered (tilegraph's own shading) — and written for the test to compare: `none` and
 * `hiz-2phase` must be equal, and differ from tilegraph's shading. With a cluster file
 * attached (written by the test), `none` and `hiz-2phase-clusters` must be equal.
 *
 * Usage: materials VS.spv FS.spv none|hiz-2phase|hiz-2phase-clusters|tilegraph OUT_PREFIX
 *        [CLUSTERS]
 * (writes OUT_PREFIX-0.rgba .. OUT_PREFIX-4.rgba). Exits non-zero on any failure or validation
 * message.
 */
#include "engine.h"

enum { WIDTH = 160, HEIGHT = 90, FRAMES = 5, STEP = 40, SLOTS = 2 };

/* Reads a SPIR-V file into `*words` (malloc'd); returns its size in bytes. */
static size_t read_spirv(const char *path, uint32_t **words) {
    FILE *f = fopen(path, "rb");
    CHECK(f != NULL, "cannot open %s", path);
    CHECK(fseek(f, 0, SEEK_END) == 0, "cannot seek %s", path);
    long size = ftell(f);
    CHECK(size > 0 && size % 4 == 0, "%s: size %ld is not SPIR-V", path, size);
    rewind(f);
    *words = malloc((size_t)size);
    CHECK(*words != NULL, "out of memory");
    CHECK(fread(*words, 1, (size_t)size, f) == (size_t)size, "short read of %s", path);
    fclose(f);
    return (size_t)size;
}

/* What the engine owns for its material. */
typedef struct EngineMaterial {
    VkDescriptorSetLayout set_layout;
    VkPipelineLayout layout;
    VkDescriptorPool pool;
    VkDescriptorSet set;
    VkBuffer tint;
    VkDeviceMemory tint_memory;
    uint32_t binds; /* how often tilegraph called the bind callback */
} EngineMaterial;

static EngineMaterial engine_material(const Engine *e, VkDescriptorSetLayout scene_set) {
    EngineMaterial m = {0};
    VkDescriptorSetLayoutBinding binding = {.binding = 0,
                                            .descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER,
                                            .descriptorCount = 1,
                                            .stageFlags = VK_SHADER_STAGE_FRAGMENT_BIT};
    VkDescriptorSetLayoutCreateInfo set_info = {
        .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
        .bindingCount = 1,
        .pBindings = &binding};
    VK_CHECK(vkCreateDescriptorSetLayout(e->device, &set_info, NULL, &m.set_layout));
    VkDescriptorSetLayout sets[2] = {scene_set, m.set_layout};
    VkPipelineLayoutCreateInfo layout_info = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
        .setLayoutCount = 2,
        .pSetLayouts = sets};
    VK_CHECK(vkCreatePipelineLayout(e->device, &layout_info, NULL, &m.layout));
    VkDescriptorPoolSize size = {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1};
    VkDescriptorPoolCreateInfo pool_info = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
                                            .maxSets = 1,
                                            .poolSizeCount = 1,
                                            .pPoolSizes = &size};
    VK_CHECK(vkCreateDescriptorPool(e->device, &pool_info, NULL, &m.pool));
    VkDescriptorSetAllocateInfo alloc_set = {
        .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
        .descriptorPool = m.pool,
        .descriptorSetCount = 1,
        .pSetLayouts = &m.set_layout};
    VK_CHECK(vkAllocateDescriptorSets(e->device, &alloc_set, &m.set));

    VkBufferCreateInfo buffer_info = {.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                                      .size = 16,
                                      .usage = VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT};
    VK_CHECK(vkCreateBuffer(e->device, &buffer_info, NULL, &m.tint));
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(e->device, m.tint, &req);
    VkMemoryAllocateInfo alloc = {
        .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
        .allocationSize = req.size,
        .memoryTypeIndex = engine_memory_type(e, req.memoryTypeBits,
                                              VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
                                                  VK_MEMORY_PROPERTY_HOST_COHERENT_BIT)};
    VK_CHECK(vkAllocateMemory(e->device, &alloc, NULL, &m.tint_memory));
    VK_CHECK(vkBindBufferMemory(e->device, m.tint, m.tint_memory, 0));
    float *rgba;
    VK_CHECK(vkMapMemory(e->device, m.tint_memory, 0, 16, 0, (void **)&rgba));
    rgba[0] = 1.0f, rgba[1] = 0.85f, rgba[2] = 0.7f, rgba[3] = 1.0f;
    vkUnmapMemory(e->device, m.tint_memory);
    VkDescriptorBufferInfo buffer = {m.tint, 0, 16};
    VkWriteDescriptorSet write = {.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                  .dstSet = m.set,
                                  .descriptorCount = 1,
                                  .descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER,
                                  .pBufferInfo = &buffer};
    vkUpdateDescriptorSets(e->device, 1, &write, 0, NULL);
    return m;
}

static void engine_material_destroy(const Engine *e, EngineMaterial *m) {
    vkDestroyDescriptorPool(e->device, m->pool, NULL);
    vkDestroyPipelineLayout(e->device, m->layout, NULL);
    vkDestroyDescriptorSetLayout(e->device, m->set_layout, NULL);
    vkDestroyBuffer(e->device, m->tint, NULL);
    vkFreeMemory(e->device, m->tint_memory, NULL);
}

/* The bind callback: the engine's set 1, for both passes. */
static void bind_tint(void *user, void *command_buffer, uint32_t pass) {
    EngineMaterial *m = user;
    (void)pass;
    m->binds++;
    vkCmdBindDescriptorSets((VkCommandBuffer)command_buffer, VK_PIPELINE_BIND_POINT_GRAPHICS,
                            m->layout, 1, 1, &m->set, 0, NULL);
}

int main(int argc, char **argv) {
    CHECK(argc >= 5, "usage: materials VS.spv FS.spv none|hiz-2phase|hiz-2phase-clusters|tilegraph "
                     "OUT_PREFIX [CLUSTERS]");
    uint32_t culling = TG_CULLING_NONE;
    int engine_shading = 1;
    if (strcmp(argv[3], "hiz-2phase") == 0) {
        culling = TG_CULLING_HIZ_TWO_PHASE;
    } else if (strcmp(argv[3], "hiz-2phase-clusters") == 0) {
        culling = TG_CULLING_HIZ_TWO_PHASE_CLUSTERS;
    } else if (strcmp(argv[3], "tilegraph") == 0) {
        engine_shading = 0;
    } else {
        CHECK(strcmp(argv[3], "none") == 0, "unknown mode %s", argv[3]);
    }
    uint32_t *vs, *fs;
    size_t vs_size = read_spirv(argv[1], &vs), fs_size = read_spirv(argv[2], &fs);

    Engine e;
    engine_start(&e);
    engine_create_device(&e, TG_TECHNIQUE_PREPASS, culling, 0);
    TgContext context;
    TG_CHECK(engine_adopt(&e, "lavapipe", &context));
    TgScene scene;
    TG_CHECK(tg_scene_load("city:400", &scene));
    /* The scene's clusters, written on the desktop (every mode of a comparison attaches them:
     * the same index order). */
    if (argc >= 6) {
        TG_CHECK(tg_scene_attach_clusters(scene, argv[5]));
    }
    TgRendererDesc desc = {.technique = TG_TECHNIQUE_PREPASS,
                           .culling = culling,
                           .width = WIDTH,
                           .height = HEIGHT,
                           .frames_in_flight = SLOTS,
                           .clear_color = {0.55f, 0.65f, 0.78f, 1.0f}};
    TgRenderer renderer;
    TG_CHECK(tg_renderer_create(context, scene, &desc, &renderer));

    uint64_t scene_set;
    TG_CHECK(tg_renderer_scene_set_layout(renderer, &scene_set));
    EngineMaterial material = engine_material(&e, (VkDescriptorSetLayout)scene_set);
    if (engine_shading) {
        /* Depth pre-pass: its vertex shader alone; colour: both stages. */
        TgEngineMaterialDesc m = {
            .name = "toon",
            .layout = (uint64_t)material.layout,
            .depth_vertex = {.name = "test_engine.vert", .code = vs, .code_size = vs_size},
            .color_vertex = {.name = "test_engine.vert", .code = vs, .code_size = vs_size},
            .color_fragment = {.name = "test_engine.frag", .code = fs, .code_size = fs_size},
            .bind = bind_tint,
            .user = &material};
        uint32_t id;
        TG_CHECK(tg_material_register(renderer, &m, &id));
        CHECK(id == 0, "the first engine material is %u", id);
    }
    /* The city's opaque materials are the engine's. */
    uint32_t materials, opaque = 0;
    TG_CHECK(tg_scene_material_count(scene, &materials));
    for (uint32_t i = 0; i < materials; i++) {
        TgMaterial m;
        uint32_t engine;
        TG_CHECK(tg_scene_material(scene, i, &m, &engine));
        CHECK(engine == TG_ENGINE_MATERIAL_NONE, "material %u starts with engine material %u", i,
              engine);
        if (m.material_class == TG_MATERIAL_CLASS_OPAQUE) {
            TG_CHECK(tg_scene_set_engine_material(scene, i, 0));
            opaque++;
        }
    }
    CHECK(opaque > 0, "the city has no opaque material");

    EngineImage target = engine_image(&e, WIDTH, HEIGHT);
    EngineSlot slots[SLOTS] = {engine_slot(&e), engine_slot(&e)};
    for (uint32_t k = 0; k < FRAMES; k++) {
        TgCamera camera;
        TG_CHECK(tg_scene_path_camera(scene, k * STEP, &camera, NULL));
        EngineSlot *s = &slots[k % SLOTS];
        engine_begin(&e, s);
        TgTarget t = engine_frame_target(&target, WIDTH, HEIGHT, k == 0);
        TgEngineFrame frame = {.command_buffer = s->cb, .slot = k % SLOTS};
        TG_CHECK(tg_renderer_record(renderer, &camera, 0, &frame, &t));
        engine_submit(&e, s);
        VK_CHECK(vkQueueWaitIdle(e.queue));
        char path[4096];
        snprintf(path, sizeof path, "%s-%u.rgba", argv[4], k);
        engine_read_back(&e, &target, WIDTH, HEIGHT, path);
    }
    /* Once per pass and pipeline run: at least the pre-pass and the colour pass per frame. */
    CHECK(!engine_shading || material.binds >= 2 * FRAMES, "bind called %u times",
          material.binds);
    CHECK(engine_shading || material.binds == 0, "bind called without a material");

    /* A scene naming an engine material this renderer lacks is refused at record. */
    if (engine_shading) {
        TG_CHECK(tg_scene_set_engine_material(scene, 0, 7));
        TgCamera camera;
        TG_CHECK(tg_scene_path_camera(scene, 0, &camera, NULL));
        EngineSlot *s = &slots[0];
        engine_begin(&e, s);
        TgTarget t = engine_target(&target, WIDTH, HEIGHT, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                                   VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_READ_BIT);
        TgEngineFrame frame = {.command_buffer = s->cb, .slot = 0};
        CHECK(tg_renderer_record(renderer, &camera, 0, &frame, &t) ==
                  TG_STATUS_INVALID_ARGUMENT,
              "an unknown engine material was drawn");
        CHECK(strstr(tg_last_error(), "engine material 7") != NULL, "message: %s",
              tg_last_error());
        /* The command buffer holds part of a frame: it is freed unsubmitted. */
    }
    /* Malformed shaders are refused before anything is made. */
    uint32_t not_spirv[4] = {1, 2, 3, 4}, id;
    TgEngineMaterialDesc bad = {
        .layout = (uint64_t)material.layout,
        .color_vertex = {.code = not_spirv, .code_size = sizeof not_spirv},
        .color_fragment = {.code = fs, .code_size = fs_size}};
    CHECK(tg_material_register(renderer, &bad, &id) == TG_STATUS_INVALID_ARGUMENT,
          "non-SPIR-V was accepted");
    CHECK(id == TG_ENGINE_MATERIAL_NONE, "a refused material got id %u", id);
    bad.color_vertex = (TgShader){.code = vs, .code_size = vs_size};
    bad.color_fragment = (TgShader){0};
    CHECK(tg_material_register(renderer, &bad, &id) == TG_STATUS_INVALID_ARGUMENT,
          "a colour vertex shader without a fragment shader was accepted");

    TG_CHECK(tg_renderer_destroy(renderer));
    TG_CHECK(tg_scene_destroy(scene));
    TG_CHECK(tg_context_destroy(context));
    engine_material_destroy(&e, &material);
    for (int i = 0; i < SLOTS; i++) {
        engine_slot_destroy(&e, &slots[i]);
    }
    engine_image_destroy(&e, &target);
    free(vs);
    free(fs);
    int messages = engine_destroy(&e);
    CHECK(messages == 0, "%d validation message(s)", messages);
    printf("ok: %u opaque materials drawn by the engine\n", opaque);
    return 0;
}
