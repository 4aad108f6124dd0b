/*
 * A game that ships a precomputed visible set: baked on the desktop by `tilegraph pvs` (here by
 * the test, into SET.json), read as an Android game reads an asset — the file's bytes, handed
 * over from memory — and drawn with TG_CULLING_PVS along the city's path. The set is destroyed
 * as soon as the renderer is made (the renderer keeps its own reference). Its pixels equal the
 * same frames through the Rust API, bit for bit (the test compares). Then the refusals: no set,
 * a set baked for other geometry, bytes that are no set, a destroyed set's handle.
 *
 * Usage: pvs SET.json OUT.rgba. Exits non-zero on any failure or validation message.
 */
#include "engine.h"

enum { WIDTH = 160, HEIGHT = 90, FRAMES = 6, SLOTS = 2 };

/* The whole file, as an asset manager hands it over. */
static unsigned char *read_file(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    CHECK(f != NULL, "cannot open %s", path);
    CHECK(fseek(f, 0, SEEK_END) == 0, "seek");
    long n = ftell(f);
    CHECK(n > 0, "%s is empty", path);
    CHECK(fseek(f, 0, SEEK_SET) == 0, "seek");
    unsigned char *bytes = malloc((size_t)n);
    CHECK(bytes != NULL, "out of memory");
    CHECK(fread(bytes, 1, (size_t)n, f) == (size_t)n, "short read of %s", path);
    fclose(f);
    *size = (size_t)n;
    return bytes;
}

int main(int argc, char **argv) {
    CHECK(argc >= 3, "usage: pvs SET.json OUT.rgba");
    Engine e;
    engine_start(&e);
    engine_create_device(&e, TG_TECHNIQUE_FORWARD, TG_CULLING_PVS, 0);
    TgContext context;
    TG_CHECK(engine_adopt(&e, "mali-valhall", &context));
    TgScene scene;
    TG_CHECK(tg_scene_load("city:300", &scene));

    /* From memory, and from the file: the same set. */
    size_t size = 0;
    unsigned char *bytes = read_file(argv[1], &size);
    TgPvs pvs, from_file;
    TG_CHECK(tg_pvs_load_memory(bytes, size, &pvs));
    free(bytes);
    TG_CHECK(tg_pvs_load(argv[1], &from_file));
    TgPvsInfo info, file_info;
    TG_CHECK(tg_pvs_info(pvs, &info));
    TG_CHECK(tg_pvs_info(from_file, &file_info));
    uint32_t instances = 0;
    TG_CHECK(tg_scene_counts(scene, &instances, NULL));
    CHECK(info.instances == instances, "set of %u instances, scene of %u", info.instances,
          instances);
    CHECK(info.stored_ids > 0 && info.stored_ids == file_info.stored_ids &&
              info.cells[0] == file_info.cells[0] && info.cell_size[0] == file_info.cell_size[0],
          "memory and file differ");
    TG_CHECK(tg_pvs_destroy(from_file));
    printf("set: %u x %u x %u cells of %.1f m, %u samples, %llu ids\n", info.cells[0],
           info.cells[1], info.cells[2], info.cell_size[0], info.samples,
           (unsigned long long)info.stored_ids);

    TgRendererDesc desc = {.technique = TG_TECHNIQUE_FORWARD,
                           .culling = TG_CULLING_PVS,
                           .width = WIDTH,
                           .height = HEIGHT,
                           .frames_in_flight = SLOTS,
                           .clear_color = {0.55f, 0.65f, 0.78f, 1.0f},
                           .pvs = pvs,
                           .pvs_dilation = 1};
    TgRenderer renderer;
    TG_CHECK(tg_renderer_create(context, scene, &desc, &renderer));
    /* The renderer keeps the set. */
    TG_CHECK(tg_pvs_destroy(pvs));

    EngineImage target = engine_image(&e, WIDTH, HEIGHT);
    EngineSlot slots[SLOTS] = {engine_slot(&e), engine_slot(&e)};
    uint32_t drawn = 0;
    for (uint32_t i = 0; i < FRAMES; i++) {
        TgCamera camera;
        uint32_t cut;
        TG_CHECK(tg_scene_path_camera(scene, i, &camera, &cut));
        EngineSlot *s = &slots[i % SLOTS];
        engine_begin(&e, s);
        TgTarget t = engine_frame_target(&target, WIDTH, HEIGHT, i == 0);
        TgEngineFrame frame = {.command_buffer = s->cb, .slot = i % SLOTS};
        TG_CHECK(tg_renderer_record(renderer, &camera, cut, &frame, &t));
        engine_submit(&e, s);
        TgFrameStats stats;
        TG_CHECK(tg_renderer_stats(renderer, &stats));
        drawn += stats.draws;
    }
    VK_CHECK(vkQueueWaitIdle(e.queue));
    engine_read_back(&e, &target, WIDTH, HEIGHT, argv[2]);
    CHECK(drawn > 0 && drawn < FRAMES * instances, "%u draws over %u frames of %u instances",
          drawn, FRAMES, instances);
    printf("draws: %u over %u frames\n", drawn, FRAMES);

    /* The refusals. */
    TgRenderer refused;
    TgRendererDesc none = desc;
    none.pvs = (TgPvs){0};
    CHECK(tg_renderer_create(context, scene, &none, &refused) == TG_STATUS_INVALID_ARGUMENT,
          "TG_CULLING_PVS without a set was accepted");
    CHECK(strstr(tg_last_error(), "no visible set") != NULL, "message: %s", tg_last_error());
    TgPvs stale = pvs;
    CHECK(tg_pvs_info(stale, &info) == TG_STATUS_INVALID_HANDLE, "a destroyed set answered");
    CHECK(tg_renderer_create(context, scene, &desc, &refused) == TG_STATUS_INVALID_HANDLE,
          "a destroyed set was accepted");
    TgScene other;
    TG_CHECK(tg_scene_load("city:200", &other));
    TgPvs again;
    TG_CHECK(tg_pvs_load(argv[1], &again));
    desc.pvs = again;
    CHECK(tg_renderer_create(context, other, &desc, &refused) == TG_STATUS_INVALID_ARGUMENT,
          "a set baked for another scene was accepted");
    CHECK(strstr(tg_last_error(), "other geometry") != NULL, "message: %s", tg_last_error());
    const char junk[] = "{\"version\": 1, \"cells\": 3}";
    TgPvs bad;
    CHECK(tg_pvs_load_memory((const uint8_t *)junk, sizeof junk - 1, &bad) == TG_STATUS_SCENE,
          "bytes that are no set were accepted");
    CHECK(strstr(tg_last_error(), "not a visible set") != NULL, "message: %s", tg_last_error());
    CHECK(tg_pvs_load("/nonexistent/set.json", &bad) == TG_STATUS_SCENE,
          "a missing file was accepted");

    TG_CHECK(tg_pvs_destroy(again));
    TG_CHECK(tg_renderer_destroy(renderer));
    TG_CHECK(tg_scene_destroy(other));
    TG_CHECK(tg_scene_destroy(scene));
    TG_CHECK(tg_context_destroy(context));
    for (int i = 0; i < SLOTS; i++) {
        engine_slot_destroy(&e, &slots[i]);
    }
    engine_image_destroy(&e, &target);
    int messages = engine_destroy(&e);
    CHECK(messages == 0, "%d validation message(s)", messages);
    printf("ok\n");
    return 0;
}
