/*
 * The C sample: a C engine with its own Vulkan instance and device (validation and
 * synchronization validation on, every message counted) hands them to tilegraph, renders the
 * city with two-phase HiZ culling and three shadow cascades of its sun into its own image, and
 * in the same frames a second camera further along the path (the visibility buffer, HiZ, two
 * cascades of its own) into an image of tilegraph's, and from the same camera a third view shaded
 * with deferred texturing (two-phase HiZ, no shadows) — recording into its own command buffers,
 * two frames in flight, submitting itself — reads all three back, and writes them to the files
 * named by argv[1], argv[1] + ".view" and argv[1] + ".deferred" (raw RGBA8) for the test to
 * compare with the Rust path's.
 *
 * Usage: sample OUT.rgba [PROFILE]. Exits non-zero on any failure or validation message.
 */
#include "engine.h"

enum { WIDTH = 160, HEIGHT = 90, FRAMES = 6, SLOTS = 2, WHOLE_FROM = 3 };
/* The second camera: its image's size, and how far along the path it looks from. */
enum { VIEW_WIDTH = 96, VIEW_HEIGHT = 64, VIEW_AHEAD = 20 };

int main(int argc, char **argv) {
    CHECK(argc >= 2, "usage: sample OUT.rgba [PROFILE]");
    const char *profile = argc >= 3 ? argv[2] : "mali-valhall";

    Engine e;
    engine_start(&e);
    /* The device serves both cameras: the main one's features and the second one's. */
    uint32_t features = engine_features(&e, TG_TECHNIQUE_PREPASS, TG_CULLING_HIZ_TWO_PHASE) |
                        engine_features(&e, TG_TECHNIQUE_VISBUF, TG_CULLING_HIZ);
    engine_create_device(&e, TG_TECHNIQUE_PREPASS, TG_CULLING_HIZ_TWO_PHASE, features);

    TgContext context;
    TG_CHECK(engine_adopt(&e, profile, &context));
    const char *name;
    const char *reason;
    TG_CHECK(tg_context_profile(context, &name, &reason));
    printf("profile %s (%s)\n", name, reason);
    CHECK(strcmp(name, profile) == 0, "profile %s, not %s", name, profile);
    /* The profile came from TgAdoptInfo.profile, and the reason says so. */
    CHECK(strstr(reason, "TgAdoptInfo.profile") != NULL, "reason: %s", reason);

    TgScene scene;
    TG_CHECK(tg_scene_load("city:300", &scene));
    TgRendererDesc desc = {.technique = TG_TECHNIQUE_PREPASS,
                           .culling = TG_CULLING_HIZ_TWO_PHASE,
                           .width = WIDTH,
                           .height = HEIGHT,
                           .frames_in_flight = SLOTS,
                           .clear_color = {0.55f, 0.65f, 0.78f, 1.0f},
                           .shadow_cascades = 3,
                           .shadow_resolution = 512,
                           .shadow_culling = TG_SHADOW_CULLING_RECEIVERS_HIZ};
    TgRenderer renderer;
    TG_CHECK(tg_renderer_create(context, scene, &desc, &renderer));
    /* The sun low in the west-south-west, a little warm: the cascades follow it. */
    const float to_light[3] = {-0.8f, 0.45f, 0.35f};
    const float sun[3] = {0.9f, 0.85f, 0.75f};
    TG_CHECK(tg_renderer_set_light(renderer, to_light, sun));
    /* A light that points nowhere is refused, and the renderer keeps its light. */
    const float nowhere[3] = {0.0f, 0.0f, 0.0f};
    CHECK(tg_renderer_set_light(renderer, nowhere, NULL) == TG_STATUS_INVALID_ARGUMENT,
          "a zero light direction was accepted");
    CHECK(strstr(tg_last_error(), "to_light") != NULL, "error: %s", tg_last_error());

    /* A second camera, further along the path, drawn in the same frames into its own image. */
    TgCamera view_camera;
    uint32_t view_cut;
    TG_CHECK(tg_scene_path_camera(scene, VIEW_AHEAD, &view_camera, &view_cut));
    TgViewDesc view_desc = {.technique = TG_TECHNIQUE_VISBUF,
                            .culling = TG_CULLING_HIZ,
                            .width = VIEW_WIDTH,
                            .height = VIEW_HEIGHT,
                            .clear_color = {0.1f, 0.2f, 0.3f, 1.0f},
                            .shadow_cascades = 2,
                            .shadow_resolution = 256,
                            .shadow_culling = TG_SHADOW_CULLING_RECEIVERS};
    uint32_t view;
    TG_CHECK(tg_renderer_add_view(renderer, &view_desc, &view_camera, &view));
    CHECK(view == 1, "the first further view is %u, not 1", view);
    TgViewDesc deferred_desc = {.technique = TG_TECHNIQUE_DEFERRED_TEXTURING,
                                .culling = TG_CULLING_HIZ_TWO_PHASE,
                                .width = VIEW_WIDTH,
                                .height = VIEW_HEIGHT,
                                .clear_color = {0.1f, 0.2f, 0.3f, 1.0f}};
    uint32_t deferred;
    TG_CHECK(tg_renderer_add_view(renderer, &deferred_desc, &view_camera, &deferred));
    CHECK(deferred == 2, "the deferred-texturing view is %u, not 2", deferred);
    /* A view the renderer does not have is refused. */
    CHECK(tg_renderer_set_view_camera(renderer, 7, &view_camera, 0) ==
              TG_STATUS_INVALID_ARGUMENT,
          "view 7 was accepted");
    CHECK(strstr(tg_last_error(), "view 7") != NULL, "error: %s", tg_last_error());

    EngineImage target = engine_image(&e, WIDTH, HEIGHT);
    EngineSlot slots[SLOTS] = {engine_slot(&e), engine_slot(&e)};
    for (uint32_t i = 0; i < FRAMES; i++) {
        EngineSlot *s = &slots[i % SLOTS];
        engine_begin(&e, s);
        TgCamera camera;
        uint32_t cut;
        TG_CHECK(tg_scene_path_camera(scene, i, &camera, &cut));
        /* First frame: the image's content is undefined; later ones: where the last left it. */
        TgTarget t = engine_frame_target(&target, WIDTH, HEIGHT, i == 0);
        TgEngineFrame frame = {.command_buffer = s->cb, .slot = i % SLOTS};
        if (i == WHOLE_FROM) {
            /* What a shipped game keeps: the whole frame's GPU time, no queries per pass (the
             * frames before keep the default, a time per pass). */
            TG_CHECK(tg_renderer_set_gpu_timing(renderer, TG_GPU_TIMING_FRAME));
        }
        TG_CHECK(tg_scene_path_camera(scene, VIEW_AHEAD + i, &view_camera, &view_cut));
        TG_CHECK(tg_renderer_set_view_camera(renderer, view, &view_camera, view_cut));
        TG_CHECK(tg_renderer_set_view_camera(renderer, deferred, &view_camera, view_cut));
        TG_CHECK(tg_renderer_record(renderer, &camera, cut, &frame, &t));
        engine_submit(&e, s);

        TgFrameStats stats;
        TG_CHECK(tg_renderer_stats(renderer, &stats));
        printf("frame %llu: %u render passes, %u barriers, %u draws; GPU times of frame %llu: "
               "%u passes, %.3f ms\n",
               (unsigned long long)stats.frame, stats.render_passes, stats.barriers,
               stats.draws, (unsigned long long)stats.timed_frame, stats.timed_pass_count,
               stats.timed_gpu_ms);
        /* Counts of frames in flight earlier: from the third frame on, a completed one. */
        CHECK(i < SLOTS || stats.gpu_counted, "frame %u reports no GPU culling counts", i);
        if (stats.gpu_counted) {
            printf("  GPU culling of frame %llu: %u commands draw %u instances, %u culled\n",
                   (unsigned long long)stats.gpu_counted_frame, stats.gpu_commands, stats.gpu_drawn,
                   stats.gpu_culled);
        }
        for (uint32_t p = 0; p < stats.timed_pass_count; p++) {
            TgPassTime time;
            TG_CHECK(tg_renderer_pass_time(renderer, p, &time));
            printf("  %-24s %.3f ms\n", time.name, time.gpu_ms);
            /* The first frame timed whole arrives when its slot comes round. */
            CHECK(stats.timed_frame < WHOLE_FROM || strcmp(time.name, "frame") == 0,
                  "frame %llu timed pass %s", (unsigned long long)stats.timed_frame, time.name);
        }
        CHECK(i < FRAMES - 1 || (stats.timed_frame == WHOLE_FROM && stats.timed_pass_count == 1),
              "frame %u: timed frame %llu with %u timings", i,
              (unsigned long long)stats.timed_frame, stats.timed_pass_count);
    }
    VK_CHECK(vkQueueWaitIdle(e.queue));
    engine_read_back(&e, &target, WIDTH, HEIGHT, argv[1]);
    /* The view's image: left TRANSFER_SRC_OPTIMAL, its writes visible to copies. */
    TgViewImage view_image;
    TG_CHECK(tg_renderer_view_image(renderer, view, &view_image));
    CHECK(view_image.width == VIEW_WIDTH && view_image.height == VIEW_HEIGHT &&
              view_image.layout == VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
          "view image %ux%u in layout %d", view_image.width, view_image.height,
          view_image.layout);
    char view_path[1024];
    snprintf(view_path, sizeof view_path, "%s.view", argv[1]);
    EngineImage view_target = {.image = (VkImage)(uintptr_t)view_image.image};
    engine_read_back(&e, &view_target, VIEW_WIDTH, VIEW_HEIGHT, view_path);
    TgViewImage deferred_image;
    TG_CHECK(tg_renderer_view_image(renderer, deferred, &deferred_image));
    snprintf(view_path, sizeof view_path, "%s.deferred", argv[1]);
    EngineImage deferred_target = {.image = (VkImage)(uintptr_t)deferred_image.image};
    engine_read_back(&e, &deferred_target, VIEW_WIDTH, VIEW_HEIGHT, view_path);

    TG_CHECK(tg_renderer_destroy(renderer));
    TG_CHECK(tg_scene_destroy(scene));
    TG_CHECK(tg_context_destroy(context));
    for (int i = 0; i < SLOTS; i++) {
        engine_slot_destroy(&e, &slots[i]);
    }
    engine_image_destroy(&e, &target);
    /* The engine destroys its device: tilegraph never did, and left nothing alive on it. */
    int messages = engine_destroy(&e);
    CHECK(messages == 0, "%d validation message(s)", messages);
    printf("ok\n");
    return 0;
}
