/* pbrcheck's entry point to the reference MikkTSpace (mikktspace.c / mikktspace.h beside this file,
 * Morten S. Mikkelsen, zlib licence, unmodified; as vendored by pymikktspace 0.3.0 from
 * github.com/mmikk/MikkTSpace). Called through ctypes by pbrcheck.mikktspace (no Python C API, so only a
 * C compiler is needed to build it).
 *
 * pbrcheck_mikktspace(pos, nrm, uv, tri, nfaces, out) -> 1 on success, 0 on failure
 *   pos, nrm: (N, 3) float32, uv: (N, 2) float32, tri: (nfaces, 3) uint32 (indices into N),
 *   out: (nfaces * 3, 4) float32 written per face corner: MikkTSpace's tangent xyz and its fSign
 *   (bitangent = fSign * cross(N, T), along +v as the UVs are stored). */
#include <stddef.h>
#include <stdint.h>
#include "mikktspace.h"

typedef struct {
    const float *pos, *nrm, *uv;
    const uint32_t *tri;
    float *out;
    int nfaces;
} PbrMikkData;

static int num_faces(const SMikkTSpaceContext *c) { return ((PbrMikkData *)c->m_pUserData)->nfaces; }
static int num_verts(const SMikkTSpaceContext *c, const int f) { (void)c; (void)f; return 3; }

static void get_position(const SMikkTSpaceContext *c, float out[], const int f, const int v) {
    PbrMikkData *d = (PbrMikkData *)c->m_pUserData;
    const float *p = d->pos + 3 * (size_t)d->tri[3 * (size_t)f + v];
    out[0] = p[0]; out[1] = p[1]; out[2] = p[2];
}

static void get_normal(const SMikkTSpaceContext *c, float out[], const int f, const int v) {
    PbrMikkData *d = (PbrMikkData *)c->m_pUserData;
    const float *p = d->nrm + 3 * (size_t)d->tri[3 * (size_t)f + v];
    out[0] = p[0]; out[1] = p[1]; out[2] = p[2];
}

static void get_texcoord(const SMikkTSpaceContext *c, float out[], const int f, const int v) {
    PbrMikkData *d = (PbrMikkData *)c->m_pUserData;
    const float *p = d->uv + 2 * (size_t)d->tri[3 * (size_t)f + v];
    out[0] = p[0]; out[1] = p[1];
}

static void set_basic(const SMikkTSpaceContext *c, const float t[], const float sign, const int f, const int v) {
    PbrMikkData *d = (PbrMikkData *)c->m_pUserData;
    float *o = d->out + 4 * (3 * (size_t)f + v);
    o[0] = t[0]; o[1] = t[1]; o[2] = t[2]; o[3] = sign;
}

int pbrcheck_mikktspace(const float *pos, const float *nrm, const float *uv, const uint32_t *tri,
                        int nfaces, float *out) {
    SMikkTSpaceInterface iface = {0};
    iface.m_getNumFaces = num_faces;
    iface.m_getNumVerticesOfFace = num_verts;
    iface.m_getPosition = get_position;
    iface.m_getNormal = get_normal;
    iface.m_getTexCoord = get_texcoord;
    iface.m_setTSpaceBasic = set_basic;
    PbrMikkData data = {pos, nrm, uv, tri, out, nfaces};
    SMikkTSpaceContext ctx = {&iface, &data};
    return genTangSpaceDefault(&ctx) ? 1 : 0;
}
