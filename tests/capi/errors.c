/*
 * Every error status of the C ABI, driven from C: each call that must fail returns its status
 * and leaves a message naming what failed. Faults (out of memory through the context's memory
 * budget, device loss and another Vulkan error through fault injection) fail one frame
 * cleanly: the engine resets its command buffer, and the next frame records and runs.
 *
 * TG_STATUS_INTERNAL (a bug caught at the boundary) is reachable from no input by design;
 * tg_check_panic_boundary runs a deliberate one to show the boundary holds in this build.
 *
 * Exits non-zero on any unexpected status, message or validation message.
 */
#include "engine.h"

enum { WIDTH = 64, HEIGHT = 36 };

static int covered[TG_STATUS_INTERNAL + 1];

/* `got` must be `want`, with `fragment` in the message. */
static void expect(TgStatus got, TgStatus want, const char *fragment, const char *what) {
    const char *message = tg_last_error();
    CHECK(got == want, "%s: got %s (\"%s\"), want %s", what, tg_status_name((uint32_t)got),
          message, tg_status_name((uint32_t)want));
    CHECK(strstr(message, fragment) != NULL, "%s: message \"%s\" lacks \"%s\"", what, message,
          fragment);
    covered[want] = 1;
    printf("%-28s %s\n", tg_status_name((uint32_t)want), message);
}

static const TgVertex triangle[3] = {
    {{0, 0, 0}, {0, 0, 1}, {0, 0}}, {{1, 0, 0}, {0, 0, 1}, {1, 0}}, {{0, 1, 0}, {0, 0, 1}, {0, 1}}};

static TgSceneDesc small_scene(const uint32_t *indices, const TgMaterial *material,
                               const TgMesh *mesh, const TgInstance *instance) {
    TgSceneDesc d = {.name = "small",
                     .vertices = triangle,
                     .vertex_count = 3,
                     .indices = indices,
                     .index_count = 3,
                     .materials = material,
                     .material_count = 1,
                     .meshes = mesh,
                     .mesh_count = 1,
                     .instances = instance,
                     .instance_count = 1};
    return d;
}

static void argument_errors(void) {
    TgScene scene;
    expect(tg_scene_load(NULL, &scene), TG_STATUS_NULL_POINTER, "`spec` is null", "null spec");
    expect(tg_scene_load("city:10", NULL), TG_STATUS_NULL_POINTER, "`out_scene` is null",
           "null out");
    expect(tg_scene_load("/nonexistent/missing.gltf", &scene), TG_STATUS_SCENE, "missing.gltf",
           "missing file");

    uint32_t indices[3] = {0, 1, 2};
    TgMaterial material = {{1, 1, 1, 1}, TG_MATERIAL_CLASS_OPAQUE, 0.5f, 0};
    TgMesh mesh = {0, 3, 0, 3, 0};
    TgInstance instance = {{1, 0, 0, 0, 1, 0, 0, 0, 1}, {0, 0, -5}, 0};
    TgSceneDesc desc = small_scene(indices, &material, &mesh, &instance);
    TG_CHECK(tg_scene_create(&desc, &scene));

    uint32_t bad_indices[3] = {0, 1, 7};
    TgSceneDesc bad = small_scene(bad_indices, &material, &mesh, &instance);
    expect(tg_scene_create(&bad, &scene), TG_STATUS_SCENE, "index 7", "index out of range");

    /* Vertices one byte off their alignment. */
    static unsigned char bytes[sizeof triangle + 8];
    memcpy(bytes + 1, triangle, sizeof triangle);
    bad = small_scene(indices, &material, &mesh, &instance);
    bad.vertices = (const TgVertex *)(const void *)(bytes + 1);
    expect(tg_scene_create(&bad, &scene), TG_STATUS_MISALIGNED, "`desc->vertices`",
           "misaligned vertices");

    TgMaterial bad_material = material;
    bad_material.material_class = 9;
    bad = small_scene(indices, &bad_material, &mesh, &instance);
    expect(tg_scene_create(&bad, &scene), TG_STATUS_INVALID_ARGUMENT, "material_class 9",
           "unknown material class");
    bad = small_scene(indices, &material, &mesh, &instance);
    bad.instance_count = 0;
    expect(tg_scene_create(&bad, &scene), TG_STATUS_INVALID_ARGUMENT, "needs instances",
           "zero instances");

    /* Handles: zero, destroyed, of another kind. */
    TgScene made;
    TG_CHECK(tg_scene_create(&desc, &made));
    TgRenderer none = {0};
    TgFrameStats stats;
    expect(tg_renderer_stats(none, &stats), TG_STATUS_INVALID_HANDLE, "null handle",
           "zero handle");
    TgContext not_a_context = {made.raw};
    expect(tg_context_destroy(not_a_context), TG_STATUS_INVALID_HANDLE,
           "is a TgScene handle, not a TgContext", "wrong kind");
    TG_CHECK(tg_scene_destroy(made));
    uint32_t instances;
    expect(tg_scene_counts(made, &instances, NULL), TG_STATUS_INVALID_HANDLE, "destroyed",
           "destroyed handle");
    TG_CHECK(tg_scene_destroy(scene));

    /* The compiler: a pass reading what nothing wrote; an unknown profile. */
    TgGraph graph;
    TG_CHECK(tg_graph_create(&graph));
    uint32_t color, never_written, pass;
    TG_CHECK(tg_graph_create_image(graph, "color", WIDTH, HEIGHT, VK_FORMAT_R8G8B8A8_UNORM,
                                   &color));
    TG_CHECK(tg_graph_create_image(graph, "never-written", WIDTH, HEIGHT,
                                   VK_FORMAT_R8G8B8A8_UNORM, &never_written));
    TG_CHECK(tg_graph_add_pass(graph, "post", 1, TG_PASS_CLASS_POST, &pass));
    TG_CHECK(tg_pass_color(graph, pass, color, NULL));
    TG_CHECK(tg_pass_use(graph, pass, never_written, TG_USE_SAMPLED));
    TG_CHECK(tg_graph_export(graph, color));
    TgPlan plan;
    expect(tg_graph_compile(graph, "mali-valhall", &plan), TG_STATUS_GRAPH, "never-written",
           "read before write");
    expect(tg_graph_compile(graph, "no-such-profile", &plan), TG_STATUS_PROFILE,
           "no-such-profile", "unknown profile");
    expect(tg_graph_add_pass(graph, "x", 1, 42, &pass), TG_STATUS_INVALID_ARGUMENT,
           "pass class 42", "unknown pass class");
    TG_CHECK(tg_graph_destroy(graph));
}

/* Records one frame of `renderer` into `s`; on failure the command buffer is reset, not
 * submitted. Returns the status. */
static TgStatus frame(Engine *e, EngineSlot *s, TgRenderer renderer, TgScene scene,
                      const EngineImage *img, uint32_t index, int *first) {
    engine_begin(e, s);
    TgCamera camera;
    uint32_t cut;
    TG_CHECK(tg_scene_path_camera(scene, index, &camera, &cut));
    TgTarget t = engine_frame_target(img, WIDTH, HEIGHT, *first);
    TgEngineFrame f = {.command_buffer = s->cb, .slot = 0};
    TgStatus status = tg_renderer_record(renderer, &camera, cut, &f, &t);
    if (status == TG_STATUS_OK) {
        engine_submit(e, s);
        *first = 0;
    } else {
        /* Never submitted: the next begin resets it, whatever it holds. */
    }
    return status;
}

static void device_errors(void) {
    Engine e;
    engine_start(&e);
    engine_create_device(&e, TG_TECHNIQUE_FORWARD, TG_CULLING_FRUSTUM, 0);
    TgContext context;
    TG_CHECK(engine_adopt(&e, NULL, &context));
    TgScene scene;
    TG_CHECK(tg_scene_load("city:100", &scene));
    TgRendererDesc desc = {.technique = TG_TECHNIQUE_FORWARD,
                           .culling = TG_CULLING_FRUSTUM,
                           .width = WIDTH,
                           .height = HEIGHT,
                           .frames_in_flight = 1,
                           .clear_color = {0, 0, 0, 1}};
    TgRenderer renderer;
    TgRendererDesc zero = desc;
    zero.width = 0;
    expect(tg_renderer_create(context, scene, &zero, &renderer), TG_STATUS_INVALID_ARGUMENT,
           "must all be non-zero", "zero width");
    TgRendererDesc many = desc;
    many.frames_in_flight = 17;
    expect(tg_renderer_create(context, scene, &many, &renderer), TG_STATUS_INVALID_ARGUMENT,
           "more than 16", "too many frames in flight");
    TgRendererDesc unknown = desc;
    unknown.culling = 99;
    expect(tg_renderer_create(context, scene, &unknown, &renderer), TG_STATUS_INVALID_ARGUMENT,
           "culling 99", "unknown culling");
    TG_CHECK(tg_renderer_create(context, scene, &desc, &renderer));
    expect(tg_context_destroy(context), TG_STATUS_IN_USE, "destroy them first",
           "context in use");
    expect(tg_scene_destroy(scene), TG_STATUS_IN_USE, "destroy them first", "scene in use");

    EngineImage img = engine_image(&e, WIDTH, HEIGHT);
    EngineSlot s = engine_slot(&e);
    int first = 1;
    TG_CHECK(frame(&e, &s, renderer, scene, &img, 0, &first));
    /* Stage bits tilegraph does not know never reach a barrier (the command buffer is not
     * submitted; the next begin resets it). */
    engine_begin(&e, &s);
    TgCamera camera;
    uint32_t cut;
    TG_CHECK(tg_scene_path_camera(scene, 1, &camera, &cut));
    TgTarget odd = engine_frame_target(&img, WIDTH, HEIGHT, first);
    odd.initial.stages = ~(VkPipelineStageFlags2)0;
    TgEngineFrame odd_frame = {.command_buffer = s.cb, .slot = 0};
    expect(tg_renderer_record(renderer, &camera, cut, &odd_frame, &odd),
           TG_STATUS_INVALID_ARGUMENT, "initial.stages", "unknown stage bits");

    /* Out of memory: the budget at what tilegraph holds; a new plan needs more. */
    TgRenderer second;
    desc.culling = TG_CULLING_NONE;
    TG_CHECK(tg_renderer_create(context, scene, &desc, &second));
    uint64_t held;
    TG_CHECK(tg_context_memory(context, &held));
    TG_CHECK(tg_context_set_memory_budget(context, held));
    int second_first = 1;
    expect(frame(&e, &s, second, scene, &img, 0, &second_first), TG_STATUS_OUT_OF_MEMORY,
           "out of device memory", "memory budget");
    TG_CHECK(tg_context_set_memory_budget(context, 0));
    TG_CHECK(frame(&e, &s, second, scene, &img, 1, &second_first));
    TG_CHECK(tg_renderer_destroy(second));

    /* Injected faults: one frame fails, the next records and runs. */
    TG_CHECK(tg_context_inject_fault(context, VK_ERROR_UNKNOWN));
    expect(frame(&e, &s, renderer, scene, &img, 1, &first), TG_STATUS_VULKAN, "injected fault",
           "injected Vulkan error");
    expect(tg_context_inject_fault(context, VK_SUCCESS), TG_STATUS_INVALID_ARGUMENT,
           "not an error code", "injecting success");
    TG_CHECK(frame(&e, &s, renderer, scene, &img, 2, &first));
    /* Inside a frame: a new renderer's first frame makes its pipelines, and fails there; its
     * next frame makes them and runs. */
    TgRenderer third;
    desc.culling = TG_CULLING_NONE;
    TG_CHECK(tg_renderer_create(context, scene, &desc, &third));
    TG_CHECK(tg_context_inject_fault_at(context, TG_FAULT_SITE_PIPELINE_CREATION,
                                        VK_ERROR_OUT_OF_DEVICE_MEMORY));
    int third_first = 1;
    expect(frame(&e, &s, third, scene, &img, 0, &third_first), TG_STATUS_OUT_OF_MEMORY,
           "vkCreateGraphicsPipelines (injected fault)", "injected at pipeline creation");
    TG_CHECK(frame(&e, &s, third, scene, &img, 1, &third_first));
    TG_CHECK(tg_renderer_destroy(third));
    expect(tg_context_inject_fault_at(context, 99, VK_ERROR_UNKNOWN), TG_STATUS_INVALID_ARGUMENT,
           "fault site 99", "unknown fault site");
    /* Device lost, last: the contract is to destroy the renderers, the context, then the
     * device, and record nothing more on any of them. */
    TG_CHECK(tg_context_inject_fault(context, VK_ERROR_DEVICE_LOST));
    expect(frame(&e, &s, renderer, scene, &img, 3, &first), TG_STATUS_DEVICE_LOST,
           "device was lost", "injected device loss");
    VK_CHECK(vkQueueWaitIdle(e.queue));

    TG_CHECK(tg_renderer_destroy(renderer));
    TG_CHECK(tg_scene_destroy(scene));
    TG_CHECK(tg_context_destroy(context));
    engine_slot_destroy(&e, &s);
    engine_image_destroy(&e, &img);
    int messages = engine_destroy(&e);
    CHECK(messages == 0, "%d validation message(s)", messages);
}

/* A device created with only what the executor needs: the renderer that wants more says which
 * feature and what wants it. */
static void missing_feature(void) {
    Engine e;
    engine_start(&e);
    engine_create_device(&e, TG_TECHNIQUE_PREPASS, TG_CULLING_OQ,
                         TG_FEATURE_SYNCHRONIZATION2 | TG_FEATURE_DYNAMIC_RENDERING);
    TgContext context;
    TG_CHECK(engine_adopt(&e, NULL, &context));
    TgScene scene;
    TG_CHECK(tg_scene_load("city:50", &scene));
    TgRendererDesc desc = {.technique = TG_TECHNIQUE_PREPASS,
                           .culling = TG_CULLING_OQ,
                           .width = WIDTH,
                           .height = HEIGHT,
                           .frames_in_flight = 2};
    TgRenderer renderer;
    expect(tg_renderer_create(context, scene, &desc, &renderer), TG_STATUS_MISSING_FEATURE,
           "culling oq needs device feature HostQueryReset", "missing feature");
    TG_CHECK(tg_scene_destroy(scene));
    TG_CHECK(tg_context_destroy(context));
    int messages = engine_destroy(&e);
    CHECK(messages == 0, "%d validation message(s)", messages);
}

int main(void) {
    argument_errors();
    device_errors();
    missing_feature();
    expect(tg_check_panic_boundary(), TG_STATUS_INTERNAL, "internal error",
           "the panic boundary");
    for (int s = TG_STATUS_NULL_POINTER; s <= TG_STATUS_INTERNAL; s++) {
        CHECK(covered[s], "status %s was not driven", tg_status_name((uint32_t)s));
    }
    CHECK(strcmp(tg_status_name(999), "TG_STATUS_UNKNOWN") == 0, "unknown status name");
    printf("ok\n");
    return 0;
}
