/* test_scene.c: the JSON parser and the scene loader (DESIGN.md §4).
 *
 * Usage: test_scene CASE DIR. Each case writes its scene files into DIR
 * (under the build directory, named after the case so that parallel ctest
 * runs never share a file) and checks either the loaded values or that the
 * load fails with BK_ERR_INPUT and a message naming file:line:col, the key
 * path and what was expected. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "json.h"
#include "scene.h"
#include "test_util.h"

/* Writes DIR/NAME and returns its path (static buffer). */
static const char *write_scene(const char *name, const char *text) {
  static char path[1024];
  snprintf(path, sizeof path, "%s/%s", tu_dir, name);
  FILE *f = fopen(path, "wb");
  if (!f || fwrite(text, 1, strlen(text), f) != strlen(text) || fclose(f) != 0) {
    fprintf(stderr, "cannot write %s: %s\n", path, strerror(errno));
    exit(1);
  }
  return path;
}

static void check_has(const char *msg, const char *want) {
  if (!strstr(msg, want)) {
    fprintf(stderr, "message \"%s\"\n  lacks \"%s\"\n", msg, want);
    tu_failures++;
  }
}

/* Loads NAME (written from text) and expects BK_ERR_INPUT with every
 * NULL-terminated substring in the message. */
static void expect_error(const char *name, const char *text, const char *const *want) {
  scene_t s;
  bk_error_t err = {0};
  const char *path = write_scene(name, text);
  int rc = scene_load(path, &s, &err);
  printf("%s -> rc %d: %s\n", name, rc, err.msg);
  EXPECT(rc == BK_ERR_INPUT);
  EXPECT(err.code == BK_ERR_INPUT);
  for (; *want; want++) check_has(err.msg, *want);
  EXPECT(s.objects == NULL && s.lights == NULL); /* nothing left allocated */
  scene_free(&s);                               /* and freeing again is safe */
}
#define EXPECT_ERROR(name, text, ...) \
  expect_error(name, text, (const char *const[]){__VA_ARGS__, NULL})

/* Loads a scene that must succeed, with stderr (the warnings) captured into
 * *warnings (caller frees). */
static int load_ok(const char *name, const char *text, scene_t *s, char **warnings) {
  char log[1024];
  bk_error_t err = {0};
  const char *path = write_scene(name, text);
  snprintf(log, sizeof log, "%s/%s.stderr", tu_dir, name);
  fflush(stderr);
  int saved = dup(2), fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (saved < 0 || fd < 0) exit(1);
  dup2(fd, 2);
  int rc = scene_load(path, s, &err);
  fflush(stderr);
  dup2(saved, 2);
  close(fd);
  close(saved);
  size_t len;
  bk_error_t rerr;
  if (bk_read_file(log, warnings, &len, &rerr)) exit(1);
  printf("%s -> rc %d %s\nwarnings:\n%s", name, rc, err.msg, *warnings);
  if (rc) fprintf(stderr, "%s: unexpected failure: %s\n", name, err.msg);
  return rc;
}

/* --- the example of DESIGN.md §4, verbatim -------------------------------- */

static const char *k_design_example =
    "{\n"
    "  \"grid\":    { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 128, \"ior_smoothing\": 2.0 },\n"
    "  \"medium\":  { \"sigma_s\": [0.5,0.5,0.5], \"sigma_a\": [0.02,0.02,0.02], \"ior\": 1.0,\n"
    "               \"density_vdb\": { \"file\": \"smoke.vdb\", \"grid\": \"density\" },\n"
    "               \"ior_vdb\":     { \"file\": \"field.vdb\", \"grid\": \"ior\" } },\n"
    "  \"objects\": [ { \"mesh\": \"meshes/armadillo.obj\", \"ior\": 1.5,\n"
    "                 \"sigma_a\": [0.0,0.0,0.0], \"sigma_s\": [0.0,0.0,0.0],\n"
    "                 \"transform\": { \"scale\": 0.01, \"rotate_deg\": [0,180,0], \"translate\": [0,0,0] } } ],\n"
    "  \"lights\":  [ { \"type\": \"spot\", \"position\": [0,3,0], \"direction\": [0,-1,0],\n"
    "                 \"angle_deg\": 20, \"intensity\": [10,10,10] },\n"
    "               { \"type\": \"directional\", \"direction\": [0,-1,0], \"irradiance\": [1,1,1] },\n"
    "               { \"type\": \"point\", \"position\": [0,2,0], \"intensity\": [5,5,5] } ],\n"
    "  \"photons\": { \"mode\": \"reference\", \"count\": 122000, \"seed\": 1, \"integrator\": \"euler\", \"step\": 0.5 },\n"
    "  \"adaptive\":{ \"pilot\": 4000, \"gradient_threshold\": \"auto\", \"luminance_threshold\": \"auto\", \"alpha\": 1.0 },\n"
    "  \"camera\":  { \"position\": [0,0.6,-3.2], \"look_at\": [0,0,0], \"up\": [0,1,0],\n"
    "               \"fov_deg\": 40, \"resolution\": [800,600] },\n"
    "  \"background\": [0,0,0]\n"
    "}\n";

static void case_full(void) {
  scene_t s;
  char *warn = NULL, want[1200];
  if (load_ok("full.json", k_design_example, &s, &warn)) {
    tu_failures++;
    free(warn);
    return;
  }
  EXPECT(warn[0] == 0); /* every key of the contract is known */
  EXPECT(s.bounds_min[0] == -1 && s.bounds_max[2] == 1 && s.resolution == 128);
  EXPECT_NEAR(s.ior_smoothing, 2.0, 0);
  snprintf(want, sizeof want, "%s/full.json:2:62: grid.resolution", tu_dir);
  EXPECT(strcmp(s.where_resolution, want) == 0);
  EXPECT_NEAR(s.medium_sigma_s[1], 0.5, 0);
  EXPECT_NEAR(s.medium_sigma_a[2], 0.02, 1e-9);
  EXPECT(s.density_vdb.present && s.ior_vdb.present);
  snprintf(want, sizeof want, "%s/smoke.vdb", tu_dir);
  EXPECT(strcmp(s.density_vdb.file, want) == 0);
  EXPECT(strcmp(s.density_vdb.grid, "density") == 0 && strcmp(s.ior_vdb.grid, "ior") == 0);
  check_has(s.ior_vdb.where, "full.json:5:41: medium.ior_vdb.file");
  EXPECT(s.object_count == 1);
  snprintf(want, sizeof want, "%s/meshes/armadillo.obj", tu_dir);
  EXPECT(strcmp(s.objects[0].mesh, want) == 0);
  check_has(s.objects[0].where, "full.json:6:26: objects[0].mesh");
  EXPECT_NEAR(s.objects[0].ior, 1.5, 0);
  EXPECT_NEAR(s.objects[0].scale[0], 0.01, 1e-9);
  EXPECT_NEAR(s.objects[0].scale[2], 0.01, 1e-9); /* a number scales all axes */
  EXPECT_NEAR(s.objects[0].rotate_deg[1], 180, 0);
  EXPECT(s.light_count == 3);
  EXPECT(s.lights[0].type == LIGHT_SPOT && s.lights[1].type == LIGHT_DIRECTIONAL &&
        s.lights[2].type == LIGHT_POINT);
  EXPECT_NEAR(s.lights[0].angle_deg, 20, 0);
  EXPECT_NEAR(s.lights[0].direction[1], -1, 0);
  EXPECT_NEAR(s.lights[0].intensity[2], 10, 0);
  EXPECT_NEAR(s.lights[1].irradiance[0], 1, 0);
  EXPECT_NEAR(s.lights[2].position[1], 2, 0);
  EXPECT(s.mode == MODE_REFERENCE && s.photon_count == 122000 && s.seed == 1);
  EXPECT(s.integrator == INTEGRATOR_EULER);
  EXPECT_NEAR(s.step, 0.5, 0);
  EXPECT(s.pilot == 4000 && s.gradient_threshold == SCENE_AUTO &&
        s.luminance_threshold == SCENE_AUTO);
  EXPECT(s.camera.present && s.camera.width == 800 && s.camera.height == 600);
  EXPECT_NEAR(s.camera.position[2], -3.2, 1e-6);
  EXPECT_NEAR(s.camera.fov_deg, 40, 0);
  EXPECT(s.hash == bk_hash64(k_design_example, strlen(k_design_example), BK_HASH_SEED));
  EXPECT(strcmp(scene_light_type_name(s.lights[0].type), "spot") == 0);
  EXPECT(strcmp(scene_mode_name(MODE_ADAPTIVE), "adaptive") == 0);
  EXPECT(strcmp(scene_integrator_name(INTEGRATOR_RK4), "rk4") == 0);
  scene_free(&s);
  scene_free(&s);
  free(warn);
}

/* A minimal scene: every default, a direction to normalise, grey colours. */
static void case_defaults(void) {
  scene_t s;
  char *warn = NULL;
  const char *text = "{ \"grid\": { \"bounds\": [[0,0,0],[2,1,1]], \"resolution\": 64.0 },\n"
                     "  \"objects\": [ { \"mesh\": \"/abs/ball.obj\", \"sigma_s\": 0.25,\n"
                     "                   \"transform\": { \"scale\": [1, 2, 3] } } ],\n"
                     "  \"lights\": [ { \"type\": \"directional\", \"direction\": [3, 0, -4],\n"
                     "                \"irradiance\": 2 } ],\n"
                     "  \"adaptive\": { \"gradient_threshold\": 0.5 },\n"
                     "  \"photons\": { \"mode\": \"adaptive\", \"integrator\": \"rk4\", \"count\": 1e6 }\n"
                     "}\n";
  if (load_ok("defaults.json", text, &s, &warn)) {
    tu_failures++;
    free(warn);
    return;
  }
  EXPECT(warn[0] == 0);
  EXPECT(s.resolution == 64); /* 64.0 is an integer */
  EXPECT_NEAR(s.ior_smoothing, 2, 0);
  EXPECT_NEAR(s.medium_ior, 1, 0);
  EXPECT(s.medium_sigma_s[0] == 0 && s.medium_sigma_a[2] == 0);
  EXPECT(!s.density_vdb.present && !s.ior_vdb.present);
  EXPECT(s.object_count == 1);
  EXPECT(strcmp(s.objects[0].mesh, "/abs/ball.obj") == 0); /* absolute stays as is */
  EXPECT_NEAR(s.objects[0].ior, 1.5, 0);
  EXPECT_NEAR(s.objects[0].sigma_s[2], 0.25, 0);
  EXPECT(s.objects[0].sigma_a[0] == 0);
  EXPECT(s.objects[0].scale[0] == 1 && s.objects[0].scale[1] == 2 && s.objects[0].scale[2] == 3);
  EXPECT(s.objects[0].translate[0] == 0 && s.objects[0].rotate_deg[2] == 0);
  EXPECT(s.light_count == 1);
  EXPECT_NEAR(s.lights[0].direction[0], 0.6, 1e-7);
  EXPECT_NEAR(s.lights[0].direction[1], 0.0, 0);
  EXPECT_NEAR(s.lights[0].direction[2], -0.8, 1e-7);
  EXPECT_NEAR(s.lights[0].irradiance[1], 2, 0);
  EXPECT(s.mode == MODE_ADAPTIVE && s.integrator == INTEGRATOR_RK4);
  EXPECT(s.photon_count == 1000000 && s.seed == 1);
  EXPECT_NEAR(s.step, 0.5, 0);
  EXPECT(s.pilot == 4000);
  EXPECT_NEAR(s.gradient_threshold, 0.5, 0);
  EXPECT(s.luminance_threshold == SCENE_AUTO);
  EXPECT_NEAR(s.alpha, 1, 0);
  EXPECT(!s.camera.present);
  EXPECT(s.camera.up[1] == 1 && s.camera.fov_deg == 40 && s.camera.width == 800 &&
        s.camera.height == 600);
  EXPECT(s.background[0] == 0 && s.background[1] == 0 && s.background[2] == 0);
  scene_free(&s);
  free(warn);
}

/* --- JSON syntax ---------------------------------------------------------- */

static void case_missing_comma(void) {
  EXPECT_ERROR("missing_comma.json",
               "{\n"
               "  \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]]\n"
               "            \"resolution\": 64 }\n"
               "}\n",
               "missing_comma.json:3:13: ", "expected ',' or '}' after object member, found '\"'");
  EXPECT_ERROR("missing_comma_array.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1] [1,1,1]], \"resolution\": 64 } }\n",
               "missing_comma_array.json:1:35: ", "expected ',' or ']' after array element, found '['");
}

static void case_trailing_comma(void) {
  EXPECT_ERROR("trailing_comma.json",
               "{\n"
               "  \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 64, }\n"
               "}\n",
               "trailing_comma.json:2:63: ", "expected a string key after ',', found '}'");
  EXPECT_ERROR("trailing_comma_array.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1],], \"resolution\": 64 } }\n",
               "trailing_comma_array.json:1:43: ", "expected a value after ',', found ']'");
}

static void case_unterminated_string(void) {
  /* points at the opening quote of the string that never closes */
  EXPECT_ERROR("unterminated.json",
               "{\n"
               "  \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 64 },\n"
               "  \"objects\": [ { \"mesh\": \"meshes/bunny.obj } ]\n"
               "}\n",
               "unterminated.json:3:26: ", "unterminated string", "found end of line");
  EXPECT_ERROR("unterminated_eof.json", "{ \"grid\": { \"bou", "unterminated_eof.json:1:13: ",
               "found end of file");
  EXPECT_ERROR("unclosed.json", "{ \"grid\": { \"bounds\": [[0,0,0],[1,1,1]]",
               "unclosed.json:1:40: ", "expected ',' or '}' after object member, found end of file");
}

static void case_garbage_after(void) {
  EXPECT_ERROR("garbage.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 64 } }\n"
               "\n"
               "  trailing words\n",
               "garbage.json:3:3: ", "expected end of file after the JSON document, found 'trailing'");
  EXPECT_ERROR("empty.json", "  \n", "empty.json:2:1: ", "expected a value, found end of file");
  EXPECT_ERROR("bad_literal.json", "{ \"grid\": True }", "bad_literal.json:1:11: ",
               "expected a value after ':', found 'True'");
}

static void case_duplicate_key(void) {
  EXPECT_ERROR("duplicate.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]],\n"
               "            \"resolution\": 64,\n"
               "            \"resolution\": 32 } }\n",
               "duplicate.json:3:13: ", "duplicate key \"resolution\" (first given at 2:13)");
}

static void case_deep_nesting(void) {
  char text[512], name[] = "deep.json";
  int n = 0;
  n += snprintf(text + n, sizeof text - n, "{ \"grid\": ");
  for (int i = 0; i < 100; i++) text[n++] = '[';
  for (int i = 0; i < 100; i++) text[n++] = ']';
  snprintf(text + n, sizeof text - n, " }");
  /* the object is level 1, so the 64th '[' (column 11 + 63) is one too deep */
  EXPECT_ERROR(name, text, "deep.json:1:74: ", "expected at most 64 nested arrays and objects");

  /* exactly JSON_MAX_DEPTH levels still parse */
  n = 0;
  for (int i = 0; i < JSON_MAX_DEPTH; i++) text[n++] = '[';
  for (int i = 0; i < JSON_MAX_DEPTH; i++) text[n++] = ']';
  bk_error_t err = {0};
  json_value_t *v = json_parse(text, (size_t)n, "deep64", &err);
  EXPECT(v != NULL);
  json_free(v);
  n = 0;
  for (int i = 0; i <= JSON_MAX_DEPTH; i++) text[n++] = '[';
  for (int i = 0; i <= JSON_MAX_DEPTH; i++) text[n++] = ']';
  EXPECT(json_parse(text, (size_t)n, "deep65", &err) == NULL);
  check_has(err.msg, "deep65:1:65: ");
}

/* Escapes, surrogate pairs, columns counted in characters, positions of
 * values and keys, and the strict corners of the grammar. */
static void case_json_strings(void) {
  const char *text = "{\"\xc3\xa9t\xc3\xa9\": \"a\\u00e9\\ud83d\\ude00\\n\\t\\\"\\\\\\/\",\n"
                     "  \"list\": [true, false, null, -0.5e2, 0, \"\\u20AC\"] }";
  bk_error_t err = {0};
  json_value_t *root = json_parse(text, strlen(text), "strings", &err);
  EXPECT(root != NULL);
  if (!root) {
    fprintf(stderr, "%s\n", err.msg);
    return;
  }
  const json_member_t *m = json_object_member(root, "\xc3\xa9t\xc3\xa9");
  EXPECT(m && m->line == 1 && m->col == 2);
  /* {"été": "a -> the value starts at character 9, byte 11 */
  EXPECT(m && m->value->line == 1 && m->value->col == 9);
  const char *want = "a\xc3\xa9\xf0\x9f\x98\x80\n\t\"\\/";
  EXPECT(m && m->value->string_len == strlen(want) && strcmp(m->value->string, want) == 0);
  const json_value_t *list = json_object_get(root, "list");
  EXPECT(list && list->type == JSON_ARRAY && list->count == 6 && list->line == 2 &&
        list->col == 11);
  if (list && list->count == 6) {
    EXPECT(list->items[0]->type == JSON_BOOL && list->items[0]->boolean == 1);
    EXPECT(list->items[1]->type == JSON_BOOL && list->items[1]->boolean == 0);
    EXPECT(list->items[2]->type == JSON_NULL && list->items[2]->col == 25);
    EXPECT(list->items[3]->type == JSON_NUMBER && list->items[3]->number == -50.0);
    EXPECT(strcmp(list->items[3]->string, "-0.5e2") == 0);
    EXPECT(strcmp(list->items[5]->string, "\xe2\x82\xac") == 0);
  }
  EXPECT(json_object_get(root, "missing") == NULL);
  json_free(root);

  static const struct {
    const char *text, *want;
  } bad[] = {
      {"[\"\\ud83d\"]", "bad:1:3: expected a low surrogate"},
      {"[\"\\ude00\"]", "bad:1:3: expected a high surrogate"},
      {"[\"\\x\"]", "bad:1:3: expected one of"},
      {"[\"\\u12G4\"]", "bad:1:3: expected 4 hex digits after '\\u', found '12G4'"},
      {"[\"a\tb\"]", "bad:1:4: expected an escape sequence such as \\t"},
      {"[\"\xff\"]", "bad:1:3: invalid UTF-8 byte 0xFF"},
      {"[01]", "bad:1:2: expected a number, found one with a leading zero"},
      {"[-x]", "bad:1:3: expected a digit after '-', found 'x'"},
      {"[1.]", "bad:1:4: expected a digit after '.', found ']'"},
      {"[1e+]", "bad:1:5: expected a digit in the exponent, found ']'"},
      {"{\"a\" 1}", "bad:1:6: expected ':' after object key, found '1'"},
      {"{1: 2}", "bad:1:2: expected a string key or '}', found '1'"},
      {"[1,\n\n   @]", "bad:3:4: expected a value after ',', found '@'"},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    bk_error_t e = {0};
    json_value_t *v = json_parse(bad[i].text, strlen(bad[i].text), "bad", &e);
    printf("%s -> %s\n", bad[i].text, e.msg);
    EXPECT(v == NULL && e.code == BK_ERR_INPUT);
    check_has(e.msg, bad[i].want);
    json_free(v);
  }
}

/* --- scene validation ------------------------------------------------------- */

static void case_missing_resolution(void) {
  EXPECT_ERROR("no_resolution.json",
               "{\n"
               "  \"grid\": {\n"
               "    \"bounds\": [[-1,-1,-1],[1,1,1]]\n"
               "  }\n"
               "}\n",
               "no_resolution.json:2:11: grid: missing required key \"resolution\"");
  EXPECT_ERROR("no_grid.json", "{ \"photons\": {} }",
               "no_grid.json:1:1: missing required key \"grid\"");
}

static void case_resolution_type(void) {
  EXPECT_ERROR("resolution_string.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]],\n"
               "            \"resolution\": \"64\" } }\n",
               "resolution_string.json:2:27: grid.resolution: expected an integer, found a string");
  EXPECT_ERROR("resolution_fraction.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 64.5 } }\n",
               "resolution_fraction.json:1:59: grid.resolution: expected an integer, found 64.5");
  EXPECT_ERROR("sigma_string.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"medium\": { \"sigma_s\": [0.5, \"0.5\", 0.5] } }\n",
               "sigma_string.json:2:32: medium.sigma_s[1]: expected a number, found a string");
  EXPECT_ERROR("bounces_word.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"photons\": { \"bounces\": \"many\" } }\n",
               "bounces_word.json:2:27: photons.bounces: expected \"auto\" or a whole number "
               "from 0 to 100000, found \"many\"");
  EXPECT_ERROR("bounces_negative.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"photons\": { \"bounces\": -1 } }\n",
               "bounces_negative.json:2:27: photons.bounces: expected an integer in [0, 100000], "
               "found -1");
  EXPECT_ERROR("g_one.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"medium\": { \"g\": 1 } }\n",
               "g_one.json:2:20: medium.g: expected a number in (-1, 1), found 1");
  EXPECT_ERROR("bounds_object.json",
               "{ \"grid\": { \"bounds\": { \"min\": [0,0,0] }, \"resolution\": 8 } }\n",
               "bounds_object.json:1:23: grid.bounds: expected [[min x,y,z], [max x,y,z]], "
               "found an object");
  EXPECT_ERROR("lights_object.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"lights\": { \"type\": \"point\" } }\n",
               "lights_object.json:2:13: lights: expected an array, found an object");
}

static void case_resolution_negative(void) {
  EXPECT_ERROR("resolution_negative.json",
               "{\n"
               "  \"grid\": {\n"
               "    \"bounds\": [[-1,-1,-1],[1,1,1]],\n"
               "    \"resolution\": -5\n"
               "  }\n"
               "}\n",
               "resolution_negative.json:4:19: grid.resolution: expected an integer >= 1, found -5");
  /* large resolutions are grid_check_memory's business, not the loader's */
  scene_t s;
  char *warn = NULL;
  EXPECT(load_ok("resolution_large.json",
                "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 100000 } }", &s,
                &warn) == BK_OK);
  EXPECT(s.resolution == 100000);
  scene_free(&s);
  free(warn);
}

static void case_bounds(void) {
  EXPECT_ERROR("bounds_inverted.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,-2,1]], \"resolution\": 8 } }\n",
               "bounds_inverted.json:1:38: grid.bounds[1][1]: expected a number > -1");
  EXPECT_ERROR("bounds_short.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1]], \"resolution\": 8 } }\n",
               "bounds_short.json:1:35: grid.bounds[1]: expected an array of 3 numbers, found an "
               "array of 2 elements");
}

static void case_spot_angle(void) {
  EXPECT_ERROR("angle.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"lights\": [\n"
               "    { \"type\": \"point\", \"position\": [0,0,0], \"intensity\": 1 },\n"
               "    { \"type\": \"spot\", \"position\": [0,3,0], \"direction\": [0,-1,0],\n"
               "      \"angle_deg\": 120, \"intensity\": [10,10,10] } ] }\n",
               "angle.json:5:20: lights[1].angle_deg: expected a number in (0, 90], found 120");
  EXPECT_ERROR("light_missing.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"lights\": [ { \"type\": \"spot\", \"position\": [0,3,0], \"angle_deg\": 20,\n"
               "                \"intensity\": 1 } ] }\n",
               "light_missing.json:2:15: lights[0]: missing required key \"direction\"");
  EXPECT_ERROR("light_zero_dir.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"lights\": [ { \"type\": \"directional\", \"direction\": [0, 0, 0],\n"
               "                \"irradiance\": 1 } ] }\n",
               "light_zero_dir.json:2:53: lights[0].direction: expected a non-zero direction, "
               "found [0, 0, 0]");
  EXPECT_ERROR("light_type.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"lights\": [ { \"type\": \"area\" } ] }\n",
               "light_type.json:2:25: lights[0].type: expected \"directional\", \"spot\" or "
               "\"point\", found \"area\"");
  EXPECT_ERROR("camera_same.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"camera\": { \"position\": [1,2,3], \"look_at\": [1,2,3] } }\n",
               "camera_same.json:2:47: camera.look_at: expected a point other than "
               "camera.position");
  EXPECT_ERROR("integrator.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"photons\": { \"integrator\": \"rk45\" } }\n",
               "integrator.json:2:30: photons.integrator: expected \"euler\" or \"rk4\", found "
               "\"rk45\"");
}

static void case_unknown_key(void) {
  scene_t s;
  char *warn = NULL;
  int rc = load_ok("unknown.json",
                   "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 16,\n"
                   "            \"ior_smoothng\": 3 },\n"
                   "  \"lights\": [ { \"type\": \"point\", \"position\": [0,0,0], \"intensity\": 1,\n"
                   "                \"angle_deg\": 30 } ],\n"
                   "  \"colour\": [1, 0, 0] }\n",
                   &s, &warn);
  EXPECT(rc == BK_OK);
  if (rc) {
    free(warn);
    return;
  }
  check_has(warn, "warning: ");
  check_has(warn, "unknown.json:2:13: grid.ior_smoothng: unknown key, ignored (did you mean "
                  "\"ior_smoothing\"?)");
  check_has(warn, "unknown.json:4:17: lights[0].angle_deg: not used by a point light, ignored");
  check_has(warn, "unknown.json:5:3: colour: unknown key, ignored");
  EXPECT(s.resolution == 16 && s.ior_smoothing == 2.0f && s.light_count == 1);
  scene_free(&s);
  free(warn);
}

static void case_huge_number(void) {
  EXPECT_ERROR("huge.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"medium\": { \"sigma_s\": [1e400, 0, 0] } }\n",
               "huge.json:2:27: medium.sigma_s[0]: expected a finite number, found 1e400");
  EXPECT_ERROR("huge_float.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8,\n"
               "            \"ior_smoothing\": -1e39 } }\n",
               "huge_float.json:2:30: grid.ior_smoothing: expected a finite number, found -1e39");
  EXPECT_ERROR("huge_resolution.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 1e12 } }\n",
               "huge_resolution.json:1:59: grid.resolution: expected an integer <= 2147483647, "
               "found 1e12");
}

/* Keyframed values (baker/scene_keys.c): linear between keys, held outside,
 * a key's own value on its frame, directions normalised; plain scenes read
 * as before (no keyed values). */
static const char *const keyed_scene =
    "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
    "  \"objects\": [ { \"mesh\": \"m.obj\", \"transform\": {\n"
    "      \"translate\": { \"keys\": { \"0\": [0, 0, 0], \"8\": [0.8, 0, 0] } } } } ],\n"
    "  \"lights\": [ { \"type\": \"spot\",\n"
    "      \"position\": { \"keys\": { \"6\": [4, 8, -4], \"2\": [0, 0, 0] } },\n"
    "      \"direction\": { \"keys\": { \"0\": [0, -2, 0], \"10\": [1, 0, 0] } },\n"
    "      \"intensity\": { \"keys\": { \"1\": 2, \"3\": [4, 6, 8] } },\n"
    "      \"angle_deg\": { \"keys\": { \"5\": 10, \"15\": 30 } } } ] }\n";

static void keyed_at(int frame, scene_t *s) {
  bk_error_t err = {0};
  const char *path = write_scene("keyed.json", keyed_scene);
  int rc = scene_load_frame(path, NULL, 0, frame, s, &err);
  printf("keyed.json at frame %d -> rc %d %s\n", frame, rc, err.msg);
  EXPECT(rc == BK_OK && s->frame == frame && s->keyed_values == 5);
}

static void case_keyframes(void) {
  scene_t s;
  const scene_light_t *l;
  keyed_at(0, &s); /* before the position's and intensity's first keys: held */
  l = &s.lights[0];
  EXPECT(l->position[0] == 0.0f && l->position[1] == 0.0f && l->intensity[0] == 2.0f &&
         l->intensity[2] == 2.0f && l->angle_deg == 10.0f);
  EXPECT(l->direction[0] == 0.0f && l->direction[1] == -1.0f); /* a key normalised */
  scene_free(&s);
  keyed_at(4, &s); /* halfway between position keys 2 and 6, 0.4 of the direction's */
  l = &s.lights[0];
  EXPECT(l->position[0] == 2.0f && l->position[1] == 4.0f && l->position[2] == -2.0f);
  EXPECT(l->intensity[0] == 4.0f && l->intensity[1] == 6.0f && l->intensity[2] == 8.0f);
  double dl = sqrt(0.4 * 0.4 + 0.6 * 0.6); /* (0, -1, 0) + 0.4 ((1, 0, 0) - (0, -1, 0)) */
  EXPECT(fabs(l->direction[0] - 0.4 / dl) < 1e-6 && fabs(l->direction[1] + 0.6 / dl) < 1e-6);
  EXPECT(fabs(s.objects[0].translate[0] - 0.4) < 1e-6);
  scene_free(&s);
  keyed_at(9, &s); /* after the last position key: held; angle 10 + 0.4 * 20 */
  l = &s.lights[0];
  EXPECT(l->position[0] == 4.0f && l->position[1] == 8.0f && fabs(l->angle_deg - 18.0) < 1e-5);
  EXPECT(s.objects[0].translate[0] == 0.8f);
  scene_free(&s);
  EXPECT_ERROR("keys_not_object.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"lights\": [ { \"type\": \"point\", \"intensity\": 1,\n"
               "      \"position\": { \"keys\": [1, 2] } } ] }\n",
               "keys_not_object.json:3:29: lights[0].position.keys: expected an object of frame");
  EXPECT_ERROR("keys_missing.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"lights\": [ { \"type\": \"point\", \"intensity\": 1,\n"
               "      \"position\": { \"1\": [0, 0, 0] } } ] }\n",
               "keys_missing.json:3:19: lights[0].position: missing required key \"keys\"");
  EXPECT_ERROR("keys_value.json",
               "{ \"grid\": { \"bounds\": [[-1,-1,-1],[1,1,1]], \"resolution\": 8 },\n"
               "  \"lights\": [ { \"type\": \"point\", \"intensity\": 1,\n"
               "      \"position\": { \"keys\": { \"1\": [0, 0, 0], \"4\": 3 } } } ] }\n",
               "keys_value.json:3:52: lights[0].position.keys.4: expected an array of 3 numbers");
}

int main(int argc, char **argv) {
  static const struct {
    const char *name;
    void (*run)(void);
  } cases[] = {
      {"full", case_full},
      {"defaults", case_defaults},
      {"missing_comma", case_missing_comma},
      {"trailing_comma", case_trailing_comma},
      {"unterminated_string", case_unterminated_string},
      {"garbage_after", case_garbage_after},
      {"duplicate_key", case_duplicate_key},
      {"deep_nesting", case_deep_nesting},
      {"json_strings", case_json_strings},
      {"missing_resolution", case_missing_resolution},
      {"resolution_type", case_resolution_type},
      {"resolution_negative", case_resolution_negative},
      {"bounds", case_bounds},
      {"spot_angle", case_spot_angle},
      {"unknown_key", case_unknown_key},
      {"huge_number", case_huge_number},
      {"keyframes", case_keyframes},
  };
  if (argc != 3) {
    fprintf(stderr, "usage: %s CASE|all DIR\n", argv[0]);
    return 2;
  }
  tu_dir = argv[2];
  if (mkdir(tu_dir, 0755) != 0 && errno != EEXIST) {
    fprintf(stderr, "%s: %s\n", tu_dir, strerror(errno));
    return 1;
  }
  int ran = 0;
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    if (strcmp(argv[1], "all") != 0 && strcmp(argv[1], cases[i].name) != 0) continue;
    cases[i].run();
    ran++;
  }
  if (!ran) {
    fprintf(stderr, "no test case named %s\n", argv[1]);
    return 2;
  }
  printf("%d failure(s)\n", tu_failures);
  return tu_failures ? 1 : 0;
}
