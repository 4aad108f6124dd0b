/*
 * The checks of the C ABI's test programs: a failed condition, VkResult or TgStatus ends the
 * program with a message naming the file, the line and (for tilegraph) tg_last_error().
 */
#ifndef TILEGRAPH_TEST_CHECK_H
#define TILEGRAPH_TEST_CHECK_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <vulkan/vulkan.h>

#include "tilegraph.h"

/* Fails the program with a message. */
#define CHECK(cond, ...)                                                        \
    do {                                                                        \
        if (!(cond)) {                                                          \
            fprintf(stderr, "%s:%d: check failed: %s: ", __FILE__, __LINE__,    \
                    #cond);                                                     \
            fprintf(stderr, __VA_ARGS__);                                       \
            fprintf(stderr, "\n");                                              \
            exit(1);                                                            \
        }                                                                       \
    } while (0)

#define VK_CHECK(call)                                                          \
    do {                                                                        \
        VkResult vk_check_result_ = (call);                                     \
        CHECK(vk_check_result_ == VK_SUCCESS, "VkResult %d", vk_check_result_); \
    } while (0)

/* A tilegraph call that must succeed. */
#define TG_CHECK(call)                                                          \
    do {                                                                        \
        TgStatus tg_check_status_ = (call);                                     \
        CHECK(tg_check_status_ == TG_STATUS_OK, "%s: %s",                       \
              tg_status_name((uint32_t)tg_check_status_), tg_last_error());     \
    } while (0)

#endif
