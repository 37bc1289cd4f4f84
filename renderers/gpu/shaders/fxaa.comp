#version 430
// FXAA 3.11 (Lottes), quality preset 12, in the LP buffer: a line-by-line port of renderers/antialias.py _fxaa
// on the padded LP buffer (lp_pad.glsl). Only the rows the inverse mapping reads (j < n[c], c < w_eff) are
// filtered; the others are copied.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "lp_cols.glsl"
#include "lp_pad.glsl"
layout(binding = 6, r32f) uniform restrict readonly image2D luma;
uniform float u_subpix;
uniform float u_edge_threshold;
uniform float u_edge_threshold_min;
const float STEPS[5] = float[5](1.0, 1.5, 2.0, 4.0, 12.0);

float lu(int x, int y) { return imageLoad(luma, pad_texel(x, y)).x; }

// Bilinear fetch at continuous padded position (x, y), pixel centres at i + 0.5, clamped (antialias._bil).
float bil_luma(float x, float y) {
    float fx = clamp(x - 0.5, 0.0, float(u_lp_w) - 1.0), fy = clamp(y - 0.5, 0.0, float(u_lp_h + 2 * PAD) - 1.0);
    int x0 = int(floor(fx)), y0 = int(floor(fy));
    int x1 = min(x0 + 1, u_lp_w - 1), y1 = min(y0 + 1, u_lp_h + 2 * PAD - 1);
    float ax = fx - float(x0), ay = fy - float(y0);
    return (lu(x0, y0) * (1.0 - ax) + lu(x1, y0) * ax) * (1.0 - ay) + (lu(x0, y1) * (1.0 - ax) + lu(x1, y1) * ax) * ay;
}
vec3 bil_rgb(float x, float y) {
    float fx = clamp(x - 0.5, 0.0, float(u_lp_w) - 1.0), fy = clamp(y - 0.5, 0.0, float(u_lp_h + 2 * PAD) - 1.0);
    int x0 = int(floor(fx)), y0 = int(floor(fy));
    int x1 = min(x0 + 1, u_lp_w - 1), y1 = min(y0 + 1, u_lp_h + 2 * PAD - 1);
    float ax = fx - float(x0), ay = fy - float(y0);
    return (src_at(pad_texel(x0, y0)) * (1.0 - ax) + src_at(pad_texel(x1, y0)) * ax) * (1.0 - ay)
        + (src_at(pad_texel(x0, y1)) * (1.0 - ax) + src_at(pad_texel(x1, y1)) * ax) * ay;
}

vec3 fxaa(int x, int y) {
    float lumaM = lu(x, y);
    float lumaS = lu(x, y + 1);
    float lumaE = lu(x + 1, y);
    float lumaN = lu(x, y - 1);
    float lumaW = lu(x - 1, y);
    float rangeMax = max(max(lumaN, lumaW), max(lumaE, max(lumaS, lumaM)));
    float rangeMin = min(min(lumaN, lumaW), min(lumaE, min(lumaS, lumaM)));
    float rng = rangeMax - rangeMin;
    if (rng < max(u_edge_threshold_min, rangeMax * u_edge_threshold)) return src_at(pad_texel(x, y));
    float lumaNW = lu(x - 1, y - 1);
    float lumaSE = lu(x + 1, y + 1);
    float lumaNE = lu(x + 1, y - 1);
    float lumaSW = lu(x - 1, y + 1);
    float lumaNS = lumaN + lumaS;
    float lumaWE = lumaW + lumaE;
    float subpixNSWE = lumaNS + lumaWE;
    float edgeHorz1 = -2.0 * lumaM + lumaNS;
    float edgeVert1 = -2.0 * lumaM + lumaWE;
    float lumaNESE = lumaNE + lumaSE;
    float lumaNWNE = lumaNW + lumaNE;
    float edgeHorz2 = -2.0 * lumaE + lumaNESE;
    float edgeVert2 = -2.0 * lumaN + lumaNWNE;
    float lumaNWSW = lumaNW + lumaSW;
    float lumaSWSE = lumaSW + lumaSE;
    float edgeHorz4 = abs(edgeHorz1) * 2.0 + abs(edgeHorz2);
    float edgeVert4 = abs(edgeVert1) * 2.0 + abs(edgeVert2);
    float edgeHorz3 = -2.0 * lumaW + lumaNWSW;
    float edgeVert3 = -2.0 * lumaS + lumaSWSE;
    float edgeHorz = abs(edgeHorz3) + edgeHorz4;
    float edgeVert = abs(edgeVert3) + edgeVert4;
    float subpixNWSWNESE = lumaNWSW + lumaNESE;
    bool horzSpan = edgeHorz >= edgeVert;
    float subpixA = subpixNSWE * 2.0 + subpixNWSWNESE;
    if (!horzSpan) {
        lumaN = lumaW;
        lumaS = lumaE;
    }
    float lengthSign = 1.0;
    float subpixB = subpixA / 12.0 - lumaM;
    float gradientN = lumaN - lumaM;
    float gradientS = lumaS - lumaM;
    float lumaNN = lumaN + lumaM;
    float lumaSS = lumaS + lumaM;
    bool pairN = abs(gradientN) >= abs(gradientS);
    float gradient = max(abs(gradientN), abs(gradientS));
    if (pairN) lengthSign = -lengthSign;
    float subpixC = clamp(abs(subpixB) / rng, 0.0, 1.0);
    float px = float(x) + 0.5, py = float(y) + 0.5;
    float bx = px, by = py;
    float ox = horzSpan ? 1.0 : 0.0, oy = horzSpan ? 0.0 : 1.0;
    if (horzSpan) by += lengthSign * 0.5;
    else bx += lengthSign * 0.5;
    float nx = bx - ox * STEPS[0], ny = by - oy * STEPS[0];
    float qx = bx + ox * STEPS[0], qy = by + oy * STEPS[0];
    float subpixD = -2.0 * subpixC + 3.0;
    if (!pairN) lumaNN = lumaSS;
    float half_ = lumaNN * 0.5;
    float lumaEndN = bil_luma(nx, ny) - half_;
    float lumaEndP = bil_luma(qx, qy) - half_;
    float subpixE = subpixC * subpixC;
    float gradientScaled = gradient * 0.25;
    bool lumaMLTZero = lumaM - half_ < 0.0;
    float subpixF = subpixD * subpixE;
    bool doneN = abs(lumaEndN) >= gradientScaled;
    bool doneP = abs(lumaEndP) >= gradientScaled;
    for (int s = 1; s < 5; s++) {
        if (doneN && doneP) break;
        if (!doneN) {
            nx -= ox * STEPS[s];
            ny -= oy * STEPS[s];
            lumaEndN = bil_luma(nx, ny) - half_;
            doneN = abs(lumaEndN) >= gradientScaled;
        }
        if (!doneP) {
            qx += ox * STEPS[s];
            qy += oy * STEPS[s];
            lumaEndP = bil_luma(qx, qy) - half_;
            doneP = abs(lumaEndP) >= gradientScaled;
        }
    }
    float dstN = horzSpan ? px - nx : py - ny;
    float dstP = horzSpan ? qx - px : qy - py;
    bool goodSpanN = (lumaEndN < 0.0) != lumaMLTZero;
    bool goodSpanP = (lumaEndP < 0.0) != lumaMLTZero;
    float spanLength = dstP + dstN;
    bool directionN = dstN < dstP;
    float dst_ = min(dstN, dstP);
    bool goodSpan = directionN ? goodSpanN : goodSpanP;
    float subpixG = subpixF * subpixF;
    float pixelOffset = -dst_ / spanLength + 0.5;
    float subpixH = subpixG * u_subpix;
    float pixelOffsetGood = goodSpan ? pixelOffset : 0.0;
    float off = max(pixelOffsetGood, subpixH);
    if (horzSpan) py += off * lengthSign;
    else px += off * lengthSign;
    return bil_rgb(px, py);
}

void main() {
    uint i = gid();
    if (i < uint(u_lp_w * u_lp_h)) {
        int c = int(i) % u_lp_w, j = int(i) / u_lp_w;
        put(ivec2(c, j), (c < u_w_eff && j < col_n(c)) ? fxaa(c, j + PAD) : src_at(ivec2(c, j)));
    }
}
