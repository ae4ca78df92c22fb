/* Framing (docs/protocol.md section 1): CRC-32C, CRC-32 (the table's), COBS, frame encoding. */
#include "fw.h"

static uint32_t crc32c_table[256];
static uint32_t crc32_table[256];
static int tables_ready;

static void make_tables(void)
{
    uint32_t i, k, c, d;
    for (i = 0; i < 256u; i++) {
        c = i;
        d = i;
        for (k = 0; k < 8u; k++) {
            c = (c & 1u) ? (c >> 1) ^ 0x82F63B78u : c >> 1; /* Castagnoli, reflected */
            d = (d & 1u) ? (d >> 1) ^ 0xEDB88320u : d >> 1; /* IEEE 802.3, reflected */
        }
        crc32c_table[i] = c;
        crc32_table[i] = d;
    }
    tables_ready = 1;
}

uint32_t fw_crc32c(const uint8_t *data, size_t n)
{
    uint32_t crc = 0xFFFFFFFFu;
    size_t i;
    if (!tables_ready)
        make_tables();
    for (i = 0; i < n; i++)
        crc = (crc >> 8) ^ crc32c_table[(crc ^ data[i]) & 0xFFu];
    return crc ^ 0xFFFFFFFFu;
}

uint32_t fw_crc32(uint32_t crc, const uint8_t *data, size_t n)
{
    size_t i;
    if (!tables_ready)
        make_tables();
    crc ^= 0xFFFFFFFFu;
    for (i = 0; i < n; i++)
        crc = (crc >> 8) ^ crc32_table[(crc ^ data[i]) & 0xFFu];
    return crc ^ 0xFFFFFFFFu;
}

size_t fw_cobs_encode(const uint8_t *in, size_t n, uint8_t *out)
{
    size_t o = 1, code_at = 0, i;
    uint8_t code = 1;
    for (i = 0; i < n; i++) {
        if (in[i] == 0) {
            out[code_at] = code;
            code_at = o++;
            code = 1;
        } else {
            out[o++] = in[i];
            code++;
            if (code == 0xFFu) {
                out[code_at] = code;
                code_at = o++;
                code = 1;
            }
        }
    }
    out[code_at] = code;
    return o;
}

int fw_cobs_decode(const uint8_t *in, size_t n, uint8_t *out, size_t cap)
{
    size_t i = 0, o = 0, end, j;
    if (n == 0)
        return -1;
    while (i < n) {
        uint8_t code = in[i];
        if (code == 0)
            return -1;
        end = i + code;
        if (end > n)
            return -1;
        for (j = i + 1; j < end; j++) {
            if (in[j] == 0 || o >= cap)
                return -1;
            out[o++] = in[j];
        }
        i = end;
        if (code < 0xFFu && i < n) {
            if (o >= cap)
                return -1;
            out[o++] = 0;
        }
    }
    return (int)o;
}

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

size_t fw_encode_frame(uint8_t type, uint32_t seq, uint32_t session, uint64_t time_us,
                       const uint8_t *body, size_t body_len, uint8_t *out)
{
    uint8_t raw[FW_MAX_DECODED];
    size_t n = 0, i, len;
    raw[n++] = (uint8_t)FW_PROTOCOL_VERSION;
    raw[n++] = type;
    put_u32(raw + n, seq);
    n += 4;
    put_u32(raw + n, session);
    n += 4;
    put_u32(raw + n, (uint32_t)time_us);
    put_u32(raw + n + 4, (uint32_t)(time_us >> 32));
    n += 8;
    if (body_len > FW_MAX_DECODED - FW_HEADER_BYTES - 4u)
        body_len = FW_MAX_DECODED - FW_HEADER_BYTES - 4u;
    for (i = 0; i < body_len; i++)
        raw[n++] = body[i];
    put_u32(raw + n, fw_crc32c(raw, n));
    n += 4;
    len = fw_cobs_encode(raw, n, out);
    out[len++] = 0;
    return len;
}

int fw_seq_after(uint32_t seq, uint32_t last)
{
    uint32_t d = seq - last;
    return d > 0u && d < 0x80000000u;
}
