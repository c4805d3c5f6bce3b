/* config_include.c: the files of a config: reading them, parsing each
   into its one YAML document (libyaml's errors translated once, here), and
   the include merge that builds one document from an include tree, each
   node remembering the file it came from. */
#include "config/config_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* Bounds on building the merged document of an include tree: nesting of
   copied nodes (the copy recurses), and nodes made by merging mappings
   relative to nodes copied (aliases to mappings could otherwise multiply
   the merged nodes exponentially). Real configs stay far below both. */
#define COPY_DEPTH_MAX       1000
#define MERGE_NODES_PER_COPY 16
#define MERGE_NODES_SLACK    4096

/* libyaml reader errors carry a byte offset, not a mark. */
static void offset_to_mark(const char *text, size_t offset, int *line, int *column)
{
    *line = 1;
    *column = 1;
    for (size_t i = 0; i < offset && text[i]; ++i) {
        if (text[i] == '\n') {
            ++*line;
            *column = 1;
        } else if (((unsigned char)text[i] & 0xC0) != 0x80) {
            ++*column;
        }
    }
}

static bool parse_error(struct loader *L, int s, const yaml_parser_t *parser, const char *text)
{
    int line, column;
    const char *problem = parser->problem ? parser->problem : "invalid YAML";
    if (parser->error == YAML_MEMORY_ERROR) return error_set(L->err, "%s: out of memory", L->sources[s].path);
    if (parser->error == YAML_READER_ERROR) {
        offset_to_mark(text, parser->problem_offset, &line, &column);
        return config_report(L, s, line, column, "%s", parser->problem ? parser->problem : "unreadable input");
    }
    line = (int)parser->problem_mark.line + 1;
    column = (int)parser->problem_mark.column + 1;
    if (parser->context)
        return config_report(L, s, line, column, "%s (%s at line %d, column %d)", problem, parser->context,
                             (int)parser->context_mark.line + 1, (int)parser->context_mark.column + 1);
    return config_report(L, s, line, column, "%s", problem);
}

/* Parses the one document of source s into doc; on success the caller
   deletes doc. */
static bool parse_document(struct loader *L, int s, const char *text, size_t length, yaml_document_t *doc)
{
    yaml_parser_t parser;
    if (!yaml_parser_initialize(&parser)) return error_set(L->err, "%s: out of memory", L->sources[s].path);
    yaml_parser_set_input_string(&parser, (const unsigned char *)text, length);
    /* On failure yaml_parser_load deletes the document itself. */
    bool ok = yaml_parser_load(&parser, doc) != 0;
    if (!ok) {
        parse_error(L, s, &parser, text);
    } else {
        yaml_document_t next;
        if (!yaml_parser_load(&parser, &next)) {
            ok = parse_error(L, s, &parser, text);
        } else {
            const yaml_node_t *root = yaml_document_get_root_node(&next);
            if (root)
                ok = config_report(L, s, (int)root->start_mark.line + 1, (int)root->start_mark.column + 1,
                                   "a second YAML document (expected exactly one)");
            yaml_document_delete(&next);
        }
        if (!ok) yaml_document_delete(doc);
    }
    yaml_parser_delete(&parser);
    return ok;
}

/* The whole of a file that is not a folder; on failure *why says what was
   wrong. */
bool config_read_text(const char *path, char **text, size_t *length, struct stat *st, const char **why)
{
    *text = NULL;
    *length = 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        *why = strerror(errno);
        return false;
    }
    /* Reading a folder would fail with EISDIR anyway; say so before. */
    if (fstat(fd, st) != 0 || S_ISDIR(st->st_mode)) {
        *why = strerror(S_ISDIR(st->st_mode) ? EISDIR : errno);
        close(fd);
        return false;
    }
    size_t cap = 1 << 16, len = 0;
    char *buf = malloc(cap);
    *why = NULL;
    while (buf) {
        if (len == cap) {
            char *grown = cap <= SIZE_MAX / 2 ? realloc(buf, cap * 2) : NULL;
            if (!grown) break;
            buf = grown;
            cap *= 2;
        }
        ssize_t got = read(fd, buf + len, cap - len);
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) {
            *why = strerror(errno);
            break;
        }
        if (got == 0) {
            close(fd);
            *text = buf;
            *length = len;
            return true;
        }
        len += (size_t)got;
    }
    if (!*why) *why = "out of memory";
    free(buf);
    close(fd);
    return false;
}

/* Building the merged document of an include tree. Every node is copied
   into L->doc with its marks, and L->node_source remembers its file, so
   that messages name the file and position the value came from. */

static bool out_of_memory(struct loader *L)
{
    return error_set(L->err, "%s: out of memory", L->file);
}

/* Adds to L->doc a node like n (a scalar with its value, an empty sequence
   or mapping) with n's marks, from source s. n may be a node of L->doc:
   everything is read from it before the node array can move. Returns the
   new id, or 0. */
static int add_like(struct loader *L, const yaml_node_t *n, int s)
{
    yaml_node_t copy = *n; /* the strings it points to do not move */
    int id = 0;
    switch (copy.type) {
    case YAML_SCALAR_NODE:
        if (copy.data.scalar.length > INT_MAX) return out_of_memory(L);
        id = yaml_document_add_scalar(&L->doc, copy.tag, copy.data.scalar.value, (int)copy.data.scalar.length,
                                      copy.data.scalar.style);
        break;
    case YAML_SEQUENCE_NODE:
        id = yaml_document_add_sequence(&L->doc, copy.tag, copy.data.sequence.style);
        break;
    case YAML_MAPPING_NODE:
        id = yaml_document_add_mapping(&L->doc, copy.tag, copy.data.mapping.style);
        break;
    case YAML_NO_NODE:
        break;
    }
    if (!id) return out_of_memory(L);
    if (id > L->cap_node_source) {
        int cap = L->cap_node_source ? 2 * L->cap_node_source : 1024;
        while (cap < id) cap *= 2;
        int *grown = realloc(L->node_source, (size_t)cap * sizeof *grown);
        if (!grown) return out_of_memory(L);
        L->node_source = grown;
        L->cap_node_source = cap;
    }
    L->node_source[id - 1] = s;
    L->n_node_source = id;
    yaml_node_t *c = config_node(L, id);
    c->start_mark = copy.start_mark;
    c->end_mark = copy.end_mark;
    return id;
}

static bool is_include_key(const yaml_node_t *key)
{
    return key->type == YAML_SCALAR_NODE && strcmp(config_text(key), "include") == 0;
}

/* Copies node id of source s's document into L->doc, once per node (memo,
   by id - 1), so that aliases stay shared and cannot multiply; the top
   level (depth 0) leaves out its include key. Returns the copy's id, or 0. */
static int copy_node(struct loader *L, int s, yaml_document_t *doc, int id, int *memo, int depth)
{
    if (memo[id - 1]) return memo[id - 1];
    const yaml_node_t *n = yaml_document_get_node(doc, id);
    if (depth > COPY_DEPTH_MAX) {
        config_report(L, s, (int)n->start_mark.line + 1, (int)n->start_mark.column + 1,
                      "nested more than %d levels deep (expected a flatter document)", COPY_DEPTH_MAX);
        return 0;
    }
    int c = add_like(L, n, s);
    if (!c) return 0;
    memo[id - 1] = c;
    ++L->n_copied;
    if (n->type == YAML_SEQUENCE_NODE) {
        for (const yaml_node_item_t *it = n->data.sequence.items.start; it < n->data.sequence.items.top; ++it) {
            int item = copy_node(L, s, doc, *it, memo, depth + 1);
            if (!item) return 0;
            if (!yaml_document_append_sequence_item(&L->doc, c, item)) return out_of_memory(L);
        }
    } else if (n->type == YAML_MAPPING_NODE) {
        for (const yaml_node_pair_t *p = n->data.mapping.pairs.start; p < n->data.mapping.pairs.top; ++p) {
            if (depth == 0 && is_include_key(yaml_document_get_node(doc, p->key))) continue;
            int key = copy_node(L, s, doc, p->key, memo, depth + 1);
            int value = key ? copy_node(L, s, doc, p->value, memo, depth + 1) : 0;
            if (!value) return 0;
            if (!yaml_document_append_mapping_pair(&L->doc, c, key, value)) return out_of_memory(L);
        }
    }
    return c;
}

/* Index of the pair of mapping `map` (in L->doc) whose key is the scalar
   `key`, or -1. */
static int find_key(struct loader *L, int map, const yaml_node_t *key)
{
    if (key->type != YAML_SCALAR_NODE) return -1;
    const yaml_node_t *m = config_node(L, map);
    for (int i = 0; i < config_map_count(m); ++i) {
        const yaml_node_t *k = config_node(L, m->data.mapping.pairs.start[i].key);
        if (k->type == YAML_SCALAR_NODE && strcmp(config_text(k), config_text(key)) == 0) return i;
    }
    return -1;
}

/* `over` merged onto `base`, both in L->doc: two mappings merge key by key
   (base's keys first, in its order, with over's value where over has the
   key, merged again when both values are mappings; then over's other keys,
   in its order); anything else is over, whole. Returns the result's id (a
   new mapping, or over itself), or 0. Each file's keys are unique
   (check_unique_keys), so a merged mapping has unique keys too. */
static int merge(struct loader *L, int base, int over, int depth)
{
    const yaml_node_t *b = config_node(L, base), *o = config_node(L, over);
    if (b->type != YAML_MAPPING_NODE || o->type != YAML_MAPPING_NODE) return over;
    if (depth > COPY_DEPTH_MAX) {
        config_fail(L, o, "mappings nested more than %d levels deep (expected a flatter document)", COPY_DEPTH_MAX);
        return 0;
    }
    if (L->n_merged >= MERGE_NODES_PER_COPY * L->n_copied + MERGE_NODES_SLACK) {
        config_fail(L, o, "merging the includes makes more than %ld mappings (expected fewer aliases of mappings)",
                    L->n_merged);
        return 0;
    }
    int m = add_like(L, o, config_source_of(L, o));
    if (!m) return 0;
    ++L->n_merged;
    int n_base = config_map_count(config_node(L, base)), n_over = config_map_count(config_node(L, over));
    for (int i = 0; i < n_base; ++i) {
        yaml_node_pair_t p = config_node(L, base)->data.mapping.pairs.start[i];
        int j = find_key(L, over, config_node(L, p.key));
        if (j >= 0) {
            yaml_node_pair_t q = config_node(L, over)->data.mapping.pairs.start[j];
            /* The key as the including file wrote it: messages point there. */
            p.key = q.key;
            p.value = merge(L, p.value, q.value, depth + 1);
            if (!p.value) return 0;
        }
        if (!yaml_document_append_mapping_pair(&L->doc, m, p.key, p.value)) return out_of_memory(L);
    }
    for (int j = 0; j < n_over; ++j) {
        yaml_node_pair_t q = config_node(L, over)->data.mapping.pairs.start[j];
        if (find_key(L, base, config_node(L, q.key)) >= 0) continue;
        if (!yaml_document_append_mapping_pair(&L->doc, m, q.key, q.value)) return out_of_memory(L);
    }
    return m;
}

/* Every mapping of a file in an include tree has unique keys, checked
   before merging: a merged mapping keeps one value per key. */
static bool check_unique_keys(struct loader *L, int s, yaml_document_t *doc)
{
    for (const yaml_node_t *n = doc->nodes.start; n < doc->nodes.top; ++n) {
        if (n->type != YAML_MAPPING_NODE) continue;
        const yaml_node_pair_t *pairs = n->data.mapping.pairs.start;
        for (int i = 1; i < config_map_count(n); ++i) {
            const yaml_node_t *key = yaml_document_get_node(doc, pairs[i].key);
            if (key->type != YAML_SCALAR_NODE) continue;
            for (int j = 0; j < i; ++j) {
                const yaml_node_t *other = yaml_document_get_node(doc, pairs[j].key);
                if (other->type == YAML_SCALAR_NODE && strcmp(config_text(other), config_text(key)) == 0)
                    return config_report(L, s, (int)key->start_mark.line + 1, (int)key->start_mark.column + 1,
                                         "duplicate key \"%.64s\" (first at line %d, column %d)", config_text(key),
                                         (int)other->start_mark.line + 1, (int)other->start_mark.column + 1);
            }
        }
    }
    return true;
}

static int resolve(struct loader *L, int s, yaml_document_t *doc, int depth);

/* A path in an include entry: a string, not a number, boolean or null. */
static bool include_path_ok(struct loader *L, int s, const yaml_node_t *entry)
{
    int line = (int)entry->start_mark.line + 1, column = (int)entry->start_mark.column + 1;
    char buf[64];
    const char *expected = "expected a path (a string) or a list of paths";
    if (entry->type != YAML_SCALAR_NODE || config_is_null(entry))
        return config_report(L, s, line, column, "%s, got %s", expected, config_describe_node(entry, buf, sizeof buf));
    const char *name = config_text(entry);
    double number;
    bool boolean = !strcmp(name, "true") || !strcmp(name, "True") || !strcmp(name, "TRUE") || !strcmp(name, "false") ||
                   !strcmp(name, "False") || !strcmp(name, "FALSE");
    if (entry->data.scalar.style == YAML_PLAIN_SCALAR_STYLE && (boolean || config_parse_literal(name, &number)))
        return config_report(L, s, line, column, "%s, got %.40s (quote it if it is a file name)", expected, name);
    if (strlen(name) != entry->data.scalar.length)
        return config_report(L, s, line, column, "path contains a NUL character");
    if (!name[0]) return config_report(L, s, line, column, "%s, got an empty string", expected);
    return true;
}

/* Appends " -> path" (or the path first) to a chain of file names. */
static void chain_add(struct config_line *chain, const char *path)
{
    config_line_append(chain, " -> ", path);
}

/* Reads, parses and resolves the file named by include entry `entry` of
   source s (at include depth `depth`). Returns the id of its merged top
   level in L->doc, or 0. */
static int include_one(struct loader *L, int s, const yaml_node_t *entry, int depth)
{
    int line = (int)entry->start_mark.line + 1, column = (int)entry->start_mark.column + 1;
    if (!include_path_ok(L, s, entry)) return 0;
    const char *name = config_text(entry), *parent = L->sources[s].path, *slash = strrchr(parent, '/');
    /* Relative to the folder of the including file, as #include "..." is. */
    size_t dir_len = name[0] == '/' || !slash ? 0 : (size_t)(slash - parent) + 1, len = dir_len + strlen(name);
    if (len >= CONFIG_PATH_MAX) {
        config_report(L, s, line, column, "include \"%.64s...\": path too long (expected at most %d bytes)", name,
                      CONFIG_PATH_MAX - 1);
        return 0;
    }
    char *path = malloc(len + 1);
    if (!path) return out_of_memory(L);
    memcpy(path, parent, dir_len);
    memcpy(path + dir_len, name, strlen(name) + 1);

    char *text;
    size_t length;
    struct stat st;
    const char *why;
    if (!config_read_text(path, &text, &length, &st, &why)) {
        config_report(L, s, line, column,
                      "include \"%s\": cannot read %s: %s (expected a YAML file; a relative path is "
                      "relative to the folder of the file that includes it)",
                      name, path, why);
        free(path);
        return 0;
    }
    for (int p = s; p >= 0; p = L->sources[p].parent) {
        if (!L->sources[p].have_id || L->sources[p].dev != st.st_dev || L->sources[p].ino != st.st_ino) continue;
        int stack[CONFIG_INCLUDE_DEPTH_MAX + 1], n = 0;
        for (int q = s; n <= CONFIG_INCLUDE_DEPTH_MAX; q = L->sources[q].parent) {
            stack[n++] = q;
            if (q == p) break;
        }
        struct config_line chain = { "", 0 };
        while (n > 0) chain_add(&chain, L->sources[stack[--n]].path);
        chain_add(&chain, path);
        config_report(L, s, line, column,
                      "include \"%s\": include cycle %s (expected files that do not include each "
                      "other)",
                      name, chain.s);
        free(path);
        free(text);
        return 0;
    }
    if (depth >= CONFIG_INCLUDE_DEPTH_MAX) {
        config_report(L, s, line, column,
                      "include \"%s\": includes nested more than %d levels deep (expected at most %d)", name,
                      CONFIG_INCLUDE_DEPTH_MAX, CONFIG_INCLUDE_DEPTH_MAX);
        free(path);
        free(text);
        return 0;
    }
    struct source *grown = realloc(L->sources, (size_t)(L->n_sources + 1) * sizeof *grown);
    if (!grown) {
        free(path);
        free(text);
        return out_of_memory(L);
    }
    L->sources = grown;
    int t = L->n_sources++;
    struct source src = { path, s, line, column, true, st.st_dev, st.st_ino };
    L->sources[t] = src;

    yaml_document_t doc;
    bool parsed = parse_document(L, t, text, length, &doc);
    free(text);
    if (!parsed) return 0;
    int r = resolve(L, t, &doc, depth + 1);
    yaml_document_delete(&doc);
    return r;
}

/* The merged top level of source s (whose document is doc, at include depth
   `depth`): its includes, in order, each merged over the previous ones,
   then the file itself merged over them. Returns its id in L->doc, or 0. */
static int resolve(struct loader *L, int s, yaml_document_t *doc, int depth)
{
    char buf[64];
    const yaml_node_t *root = yaml_document_get_root_node(doc), *inc = NULL;
    if (!root) {
        config_report(L, s, 1, 1, "empty document (expected a mapping of config keys)");
        return 0;
    }
    if (root->type != YAML_MAPPING_NODE) {
        config_report(L, s, (int)root->start_mark.line + 1, (int)root->start_mark.column + 1,
                      "expected a mapping at the top level, got %s", config_describe_node(root, buf, sizeof buf));
        return 0;
    }
    if (!check_unique_keys(L, s, doc)) return 0;
    for (const yaml_node_pair_t *p = root->data.mapping.pairs.start; p < root->data.mapping.pairs.top; ++p)
        if (is_include_key(yaml_document_get_node(doc, p->key))) inc = yaml_document_get_node(doc, p->value);
    int merged = 0;
    if (inc && !config_is_null(inc)) {
        if (inc->type == YAML_MAPPING_NODE) {
            config_report(L, s, (int)inc->start_mark.line + 1, (int)inc->start_mark.column + 1,
                          "expected a path (a string) or a list of paths, got a mapping");
            return 0;
        }
        bool list = inc->type == YAML_SEQUENCE_NODE;
        int count = list ? config_seq_count(inc) : 1;
        for (int i = 0; i < count; ++i) {
            const yaml_node_t *entry = list ? yaml_document_get_node(doc, inc->data.sequence.items.start[i]) : inc;
            int r = include_one(L, s, entry, depth);
            if (!r) return 0;
            merged = merged ? merge(L, merged, r, 0) : r;
            if (!merged) return 0;
        }
    }
    int *memo = calloc((size_t)(doc->nodes.top - doc->nodes.start), sizeof *memo);
    if (!memo) return out_of_memory(L);
    int self = copy_node(L, s, doc, (int)(root - doc->nodes.start) + 1, memo, 0);
    free(memo);
    if (!self) return 0;
    return merged ? merge(L, merged, self, 0) : self;
}

/* Source 0's document as L->doc: its own, or the merged document of its
   include tree. */
bool config_load_document(struct loader *L, const char *text, size_t length)
{
    yaml_document_t doc;
    if (!parse_document(L, 0, text, length, &doc)) return false;
    const yaml_node_t *root = yaml_document_get_root_node(&doc), *include_key = NULL;
    if (root && root->type == YAML_MAPPING_NODE)
        for (const yaml_node_pair_t *p = root->data.mapping.pairs.start; p < root->data.mapping.pairs.top; ++p) {
            const yaml_node_t *key = yaml_document_get_node(&doc, p->key);
            if (is_include_key(key)) include_key = key;
        }
    if (!include_key) {
        L->doc = doc;
        L->have_doc = true;
        L->root = root ? 1 : 0;
        return true;
    }
    bool ok;
    if (L->from_string) {
        ok = config_report(L, 0, (int)include_key->start_mark.line + 1, (int)include_key->start_mark.column + 1,
                           "include is not available for a config given as a string (expected a config file: includes "
                           "are relative to its folder)");
    } else {
        ok = yaml_document_initialize(&L->doc, NULL, NULL, NULL, 1, 1) || out_of_memory(L);
        L->have_doc = ok;
        ok = ok && (L->root = resolve(L, 0, &doc, 0)) != 0;
    }
    yaml_document_delete(&doc);
    return ok;
}
