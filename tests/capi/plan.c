/*
 * The compiler alone through C: a deferred frame (an ambient-occlusion compute pass, a G-buffer
 * with depth, lighting reading the G-buffer as input attachments and the occlusion, a post
 * pass sampling the lit image into the engine's target, and a debug pass nothing uses) compiled
 * for three profiles — a Mali and an Adreno tiler and an NVIDIA desktop GPU — and every plan
 * walked whole: steps, each render pass's attachments with their load/store ops and layouts,
 * subpasses, every barrier, and the submissions (the occlusion pass is async-capable: on the
 * profiles with async compute it goes to the second queue, beside the G-buffer). The walk is
 * written as text; the test compares it with the same graph compiled through the Rust API,
 * line for line.
 *
 * Usage: plan OUT.txt. Exits non-zero on any failure.
 */
#include <inttypes.h>

#include "check.h"

enum { W = 320, H = 180 };

static void walk(TgGraph graph, const char *profile, FILE *out) {
    TgPlan plan;
    TG_CHECK(tg_graph_compile(graph, profile, &plan));
    TgPlanSummary s;
    TG_CHECK(tg_plan_summary(plan, &s));
    fprintf(out,
            "profile %s: %u steps, %u render passes, %u barriers, %u passes, %u pruned, "
            "%u transient, traffic %" PRIu64 " of %" PRIu64 "\n",
            profile, s.step_count, s.render_pass_count, s.barrier_count, s.pass_count,
            s.pruned_count, s.transient_count, s.attachment_traffic_bytes,
            s.naive_attachment_traffic_bytes);
    for (uint32_t i = 0; i < s.step_count; i++) {
        TgStep step;
        TG_CHECK(tg_plan_step(plan, i, &step));
        const char *name = "";
        if (step.kind != TG_STEP_KIND_BARRIERS && step.kind != TG_STEP_KIND_FLUSH) {
            TG_CHECK(tg_plan_pass_name(plan, step.pass, &name));
        }
        fprintf(out, "step %u kind %u pass %s barriers %u subpasses %u attachments %u area %ux%u\n",
                i, step.kind, name, step.barrier_count, step.subpass_count,
                step.attachment_count, step.render_area_width, step.render_area_height);
        for (uint32_t a = 0; a < step.attachment_count; a++) {
            TgAttachment at;
            TG_CHECK(tg_plan_attachment(plan, i, a, &at));
            fprintf(out,
                    "  attachment %u resource %u format %d ops %d/%d stencil %d/%d layouts "
                    "%d->%d residency %u\n",
                    a, at.resource, at.format, at.load_op, at.store_op, at.stencil_load_op,
                    at.stencil_store_op, at.initial_layout, at.final_layout, at.residency);
        }
        for (uint32_t p = 0; p < step.subpass_count; p++) {
            TgSubpass sp;
            TG_CHECK(tg_plan_subpass(plan, i, p, &sp));
            const char *sp_name;
            TG_CHECK(tg_plan_pass_name(plan, sp.pass, &sp_name));
            fprintf(out, "  subpass %u pass %s colors %u inputs %u depth %d\n", p, sp_name,
                    sp.color_count, sp.input_count, sp.depth_attachment);
        }
        for (uint32_t b = 0; b < step.barrier_count; b++) {
            TgBarrier br;
            TG_CHECK(tg_plan_barrier(plan, i, b, &br));
            fprintf(out,
                    "  barrier %u resource %u image %u src %#" PRIx64 "/%#" PRIx64
                    " dst %#" PRIx64 "/%#" PRIx64 " layouts %d->%d transfer %u\n",
                    b, br.resource, br.is_image, br.src_stages, br.src_access, br.dst_stages,
                    br.dst_access, br.old_layout, br.new_layout, br.queue_transfer);
        }
    }
    /* What to submit where: each submission's queue and steps, what it waits on, the
     * ownership releases that end it. */
    for (uint32_t k = 0; k < s.submission_count; k++) {
        TgSubmission sub;
        TG_CHECK(tg_plan_submission(plan, k, &sub));
        fprintf(out, "submission %u queue %u steps %u..%u waits %u releases %u\n", k, sub.queue,
                sub.first_step, sub.end_step, sub.wait_count, sub.release_count);
        for (uint32_t w = 0; w < sub.wait_count; w++) {
            TgQueueWait wait;
            TG_CHECK(tg_plan_submission_wait(plan, k, w, &wait));
            fprintf(out, "  wait on %u at 0x%" PRIx64 "\n", wait.submission, wait.dst_stages);
        }
        for (uint32_t r = 0; r < sub.release_count; r++) {
            TgBarrier br;
            TG_CHECK(tg_plan_submission_release(plan, k, r, &br));
            fprintf(out,
                    "  release %u resource %u image %u src 0x%" PRIx64 " layouts %d->%d "
                    "transfer %u\n",
                    r, br.resource, br.is_image, br.src_stages, br.old_layout, br.new_layout,
                    br.queue_transfer);
        }
    }
    TgSubmission past_submission;
    CHECK(tg_plan_submission(plan, s.submission_count, &past_submission) ==
              TG_STATUS_INVALID_ARGUMENT,
          "a submission past the end was returned");
    /* Past the end is a status, not a read out of bounds. */
    TgStep past;
    CHECK(tg_plan_step(plan, s.step_count, &past) == TG_STATUS_INVALID_ARGUMENT,
          "a step past the end was returned");
    TG_CHECK(tg_plan_destroy(plan));
}

int main(int argc, char **argv) {
    CHECK(argc >= 2, "usage: plan OUT.txt");
    TgGraph g;
    TG_CHECK(tg_graph_create(&g));
    uint32_t albedo, normal, depth, ao, hdr, target, scratch;
    TG_CHECK(tg_graph_create_image(g, "albedo", W, H, VK_FORMAT_R8G8B8A8_UNORM, &albedo));
    TG_CHECK(tg_graph_create_image(g, "normal", W, H, VK_FORMAT_R16G16B16A16_SFLOAT, &normal));
    TG_CHECK(tg_graph_create_image(g, "depth", W, H, VK_FORMAT_D32_SFLOAT, &depth));
    TG_CHECK(tg_graph_create_buffer(g, "ao", (uint64_t)W * H * 4, &ao));
    TG_CHECK(tg_graph_create_image(g, "hdr", W, H, VK_FORMAT_R16G16B16A16_SFLOAT, &hdr));
    TgImageState undefined = {VK_IMAGE_LAYOUT_UNDEFINED, VK_PIPELINE_STAGE_2_NONE,
                              VK_ACCESS_2_NONE};
    TgImageState present = {VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_2_COPY_BIT,
                            VK_ACCESS_2_TRANSFER_READ_BIT};
    TG_CHECK(tg_graph_import_image(g, "target", W, H, VK_FORMAT_R8G8B8A8_UNORM, &undefined, 0,
                                   &present, &target));
    TG_CHECK(tg_graph_create_image(g, "scratch", W, H, VK_FORMAT_R8G8B8A8_UNORM, &scratch));

    const float black[4] = {0, 0, 0, 1};
    const float far_depth = 1.0f;
    uint32_t gbuffer, occlusion, lighting, post, debug;
    TG_CHECK(tg_graph_add_pass(g, "occlusion", 0, TG_PASS_CLASS_COMPUTE, &occlusion));
    TG_CHECK(tg_pass_use(g, occlusion, ao, TG_USE_STORAGE_WRITE));
    /* Beside the G-buffer: on the async compute queue where the profile asks for it. */
    TG_CHECK(tg_pass_async_compute(g, occlusion));
    TG_CHECK(tg_graph_add_pass(g, "gbuffer", 1, TG_PASS_CLASS_OPAQUE, &gbuffer));
    TG_CHECK(tg_pass_color(g, gbuffer, albedo, black));
    TG_CHECK(tg_pass_color(g, gbuffer, normal, black));
    TG_CHECK(tg_pass_depth(g, gbuffer, depth, &far_depth, 0));
    TG_CHECK(tg_graph_add_pass(g, "lighting", 1, TG_PASS_CLASS_OPAQUE, &lighting));
    TG_CHECK(tg_pass_use(g, lighting, albedo, TG_USE_INPUT));
    TG_CHECK(tg_pass_use(g, lighting, normal, TG_USE_INPUT));
    TG_CHECK(tg_pass_use(g, lighting, ao, TG_USE_STORAGE_READ));
    TG_CHECK(tg_pass_color(g, lighting, hdr, NULL));
    TG_CHECK(tg_graph_add_pass(g, "post", 1, TG_PASS_CLASS_POST, &post));
    TG_CHECK(tg_pass_use(g, post, hdr, TG_USE_SAMPLED));
    TG_CHECK(tg_pass_color(g, post, target, NULL));
    TG_CHECK(tg_graph_add_pass(g, "debug", 1, TG_PASS_CLASS_POST, &debug));
    TG_CHECK(tg_pass_use(g, debug, hdr, TG_USE_SAMPLED));
    TG_CHECK(tg_pass_color(g, debug, scratch, black));
    TG_CHECK(tg_graph_export(g, target));

    FILE *out = fopen(argv[1], "w");
    CHECK(out != NULL, "cannot write %s", argv[1]);
    const char *profiles[] = {"mali-valhall", "adreno-7xx", "desktop-nvidia"};
    for (int i = 0; i < 3; i++) {
        walk(g, profiles[i], out);
    }
    fclose(out);
    TG_CHECK(tg_graph_destroy(g));
    printf("ok\n");
    return 0;
}
