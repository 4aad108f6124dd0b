/*
 * A game's frame loop in C: every frame, before recording, it moves 40 of the city's instances
 * in one batch, spawns 4 instances in front of the camera and removes the 4 it spawned two
 * frames before; then it records the frame (two-phase HiZ, its own device, command buffers
 * and image). Its pixels equal those of the same changes made through the Rust API, bit for
 * bit (the test compares). Then it checks the refusals: a removed instance's handle is
 * TG_STATUS_INVALID_HANDLE, a NaN in a batch of transforms TG_STATUS_INVALID_ARGUMENT naming
 * the entry, and a refused batch moves nothing.
 *
 * Usage: moving OUT.rgba. Exits non-zero on any failure or validation message.
 */
#include <math.h>

#include "engine.h"

enum { WIDTH = 160, HEIGHT = 90, FRAMES = 8, SLOTS = 2, MOVERS = 40, SPAWNS = 4, LIFE = 2 };

int main(int argc, char **argv) {
    CHECK(argc >= 2, "usage: moving OUT.rgba");
    Engine e;
    engine_start(&e);
    engine_create_device(&e, TG_TECHNIQUE_PREPASS, TG_CULLING_HIZ_TWO_PHASE, 0);
    TgContext context;
    TG_CHECK(engine_adopt(&e, "mali-valhall", &context));

    TgScene scene;
    TG_CHECK(tg_scene_load("city:300", &scene));
    TgRendererDesc desc = {.technique = TG_TECHNIQUE_PREPASS,
                           .culling = TG_CULLING_HIZ_TWO_PHASE,
                           .width = WIDTH,
                           .height = HEIGHT,
                           .frames_in_flight = SLOTS,
                           .clear_color = {0.55f, 0.65f, 0.78f, 1.0f}};
    TgRenderer renderer;
    TG_CHECK(tg_renderer_create(context, scene, &desc, &renderer));

    /* The movers: every third instance of the city, where they stand now. */
    uint64_t movers[MOVERS];
    TgTransform base[MOVERS], moved[MOVERS];
    for (uint32_t k = 0; k < MOVERS; k++) {
        TG_CHECK(tg_scene_instance_handle(scene, 3 * k, &movers[k]));
        TG_CHECK(tg_scene_instance_transform(scene, movers[k], &base[k]));
    }
    uint64_t crate_mesh;
    TG_CHECK(tg_scene_mesh_handle(scene, 2, &crate_mesh));
    /* Spawn 3 is mirrored: it draws the crate's copy with the winding reversed. */
    TG_CHECK(tg_scene_prepare_mirroring(scene, crate_mesh));
    uint64_t spawned[FRAMES][SPAWNS];

    EngineImage target = engine_image(&e, WIDTH, HEIGHT);
    EngineSlot slots[SLOTS] = {engine_slot(&e), engine_slot(&e)};
    for (uint32_t i = 0; i < FRAMES; i++) {
        TgCamera camera;
        uint32_t cut;
        TG_CHECK(tg_scene_path_camera(scene, i, &camera, &cut));
        /* The game's changes, then the frame. */
        for (uint32_t k = 0; k < MOVERS; k++) {
            moved[k] = base[k];
            moved[k].translation[0] += (double)((i + k) % 4) * 0.5;
        }
        TG_CHECK(tg_scene_set_transforms(scene, movers, moved, MOVERS));
        TgInstanceDesc spawn[SPAWNS];
        for (uint32_t k = 0; k < SPAWNS; k++) {
            TgTransform t = {.linear = {k == 3 ? -1 : 1, 0, 0, 0, 1, 0, 0, 0, 1}};
            for (int c = 0; c < 3; c++) {
                t.translation[c] = camera.eye[c] + (camera.target[c] - camera.eye[c]) * 0.25;
            }
            t.translation[0] += (double)k * 1.5;
            spawn[k] = (TgInstanceDesc){
                .mesh = crate_mesh, .transform = t, .flags = TG_INSTANCE_CASTS_SHADOWS};
        }
        TG_CHECK(tg_scene_add_instances(scene, spawn, SPAWNS, spawned[i]));
        if (i >= LIFE) {
            TG_CHECK(tg_scene_remove_instances(scene, spawned[i - LIFE], SPAWNS));
        }

        EngineSlot *s = &slots[i % SLOTS];
        engine_begin(&e, s);
        TgTarget t = engine_frame_target(&target, WIDTH, HEIGHT, i == 0);
        TgEngineFrame frame = {.command_buffer = s->cb, .slot = i % SLOTS};
        TG_CHECK(tg_renderer_record(renderer, &camera, cut, &frame, &t));
        engine_submit(&e, s);
    }
    VK_CHECK(vkQueueWaitIdle(e.queue));
    engine_read_back(&e, &target, WIDTH, HEIGHT, argv[1]);

    /* A removed instance's handle is stale. */
    TgTransform where;
    CHECK(tg_scene_instance_transform(scene, spawned[0][0], &where) == TG_STATUS_INVALID_HANDLE,
          "a removed instance's handle was accepted");
    CHECK(strstr(tg_last_error(), "stale") != NULL, "message: %s", tg_last_error());
    CHECK(tg_scene_set_transforms(scene, spawned[0], moved, 1) == TG_STATUS_INVALID_HANDLE,
          "a removed instance was moved");
    /* A NaN in a batch names its entry, and nothing of the batch moves. */
    TgTransform before, after, bad[2] = {moved[0], moved[1]};
    bad[0].translation[0] += 100.0;
    bad[1].translation[1] = NAN;
    TG_CHECK(tg_scene_instance_transform(scene, movers[0], &before));
    CHECK(tg_scene_set_transforms(scene, movers, bad, 2) == TG_STATUS_INVALID_ARGUMENT,
          "a NaN transform was accepted");
    CHECK(strstr(tg_last_error(), "entry 1") != NULL, "message: %s", tg_last_error());
    TG_CHECK(tg_scene_instance_transform(scene, movers[0], &after));
    CHECK(before.translation[0] == after.translation[0], "a refused batch moved an instance");
    /* Unknown flag bits are refused too. */
    uint32_t odd = 1u << 7;
    CHECK(tg_scene_set_flags(scene, movers, &odd, 1) == TG_STATUS_INVALID_ARGUMENT,
          "unknown flags were accepted");

    TG_CHECK(tg_renderer_destroy(renderer));
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
