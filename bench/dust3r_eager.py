#!/usr/bin/env python3
"""DUSt3R in PyTorch eager mode: the comparator of `ffloc bench model` (docs/benchmarks.md).

Written for ffloc from the architecture facts of ../shared/fixtures/dust3r/README.md (the
fixture's own text; no DUSt3R or CroCo code). The network is plain torch.nn.functional code over
a dict of parameters named as in the reference state_dict, in the style of the reference's eager
modules: qkv split by reshape/permute, RoPE2D by the rotate-half formula with table look-ups,
q k^T, softmax, weighted sum of v, heads merged by transpose/reshape.

Two modes:
  --check DIR   runs the tiny fixture model (DIR/tiny_model.safetensors) on every case file of
                DIR and compares every tensor: max|ours - ref| <= tol * max|ref| (ffloc's parity
                test uses 1e-5), integer tensors exactly; also checks the large config's
                parameter names and shapes against DIR/large_config_keys.json.
  --bench       times the large config with random weights, as `ffloc bench model` measures it:
                (i) the encoder on one image, (ii) the decoder + both DPT heads with
                post-processing on a pair of precomputed encodings. Rows as JSON lines with
                --json (the fields of `ffloc bench model --json`).

Exit code 77 (CTest's skip) when python3-torch or the fixture folder is missing.
"""

import argparse
import json
import math
import os
import resource
import struct
import sys
import time

SKIP = 77


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", metavar="DIR", help="fixture folder (shared/fixtures/dust3r)")
    mode.add_argument("--bench", action="store_true", help="time the large config")
    parser.add_argument("--tolerance", type=float, default=1e-5, help="relative tolerance of --check")
    parser.add_argument("--threads", type=int, default=2, help="intra-op and OpenBLAS threads")
    parser.add_argument("--repeats", type=int, default=3, help="timed calls per row")
    parser.add_argument("--warmup", type=int, default=1, help="untimed calls before each row")
    parser.add_argument("--width", type=int, default=512)
    parser.add_argument("--height", type=int, default=384)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print the rows as JSON lines")
    return parser.parse_args()


ARGS = parse_args()
# OpenBLAS reads its thread count when it is loaded (by torch): set it first, as the reference
# timing did (python_reference_timing_amd.txt: without it OpenBLAS runs its own 2 threads).
if ARGS.bench:
    os.environ["OPENBLAS_NUM_THREADS"] = str(ARGS.threads)

try:
    import torch
    import torch.nn.functional as F
except ImportError:
    print("dust3r_eager: python3-torch is not installed (apt-get install python3-torch); skipped")
    sys.exit(SKIP)


class Config:
    def __init__(self, enc_dim, enc_depth, enc_heads, dec_dim, dec_depth, dec_heads, layer_dims, feature_dim,
                 last_dim, patch=16, mlp_ratio=4, eps=1e-6, rope_base=100.0):
        self.enc_dim, self.enc_depth, self.enc_heads = enc_dim, enc_depth, enc_heads
        self.dec_dim, self.dec_depth, self.dec_heads = dec_dim, dec_depth, dec_heads
        self.layer_dims, self.feature_dim, self.last_dim = list(layer_dims), feature_dim, last_dim
        self.patch, self.mlp_ratio, self.eps, self.rope_base = patch, mlp_ratio, eps, rope_base

    @property
    def hooks(self):
        d = self.dec_depth
        return [0, d * 2 // 4, d * 3 // 4, d]


LARGE = Config(1024, 24, 16, 768, 12, 12, [96, 192, 384, 768], 256, 128)


def config_from_fixture(path):
    with open(path) as f:
        c = json.load(f)
    kw, dpt = c["constructor_kwargs"], c["dpt_head"]
    return Config(kw["enc_embed_dim"], kw["enc_depth"], kw["enc_num_heads"], kw["dec_embed_dim"], kw["dec_depth"],
                  kw["dec_num_heads"], dpt["layer_dims"], dpt["feature_dim"], dpt["last_dim"], c["patch_size"],
                  c["mlp_ratio"], c["layernorm_eps"])


# ---------------------------------------------------------------------------------------------
# Parameters: name -> shape, the reference's state_dict names (aliases of the DPT layer_rn
# weights left out: they are the same tensors as scratch.layer{i}_rn.weight).

def parameter_shapes(cfg, heads=2):
    shapes = {}

    def linear(name, fan_in, fan_out):
        shapes[name + ".weight"] = (fan_out, fan_in)
        shapes[name + ".bias"] = (fan_out,)

    def norm(name, dim):
        shapes[name + ".weight"] = (dim,)
        shapes[name + ".bias"] = (dim,)

    def conv(name, cin, cout, k, bias=True):
        shapes[name + ".weight"] = (cout, cin, k, k)
        if bias:
            shapes[name + ".bias"] = (cout,)

    e, d, m = cfg.enc_dim, cfg.dec_dim, cfg.mlp_ratio
    shapes["mask_token"] = (1, 1, d)
    conv("patch_embed.proj", 3, e, cfg.patch)
    for i in range(cfg.enc_depth):
        p = "enc_blocks.%d." % i
        norm(p + "norm1", e)
        linear(p + "attn.qkv", e, 3 * e)
        linear(p + "attn.proj", e, e)
        norm(p + "norm2", e)
        linear(p + "mlp.fc1", e, m * e)
        linear(p + "mlp.fc2", m * e, e)
    norm("enc_norm", e)
    linear("decoder_embed", e, d)
    for stack in ("dec_blocks", "dec_blocks2"):
        for i in range(cfg.dec_depth):
            p = "%s.%d." % (stack, i)
            norm(p + "norm1", d)
            linear(p + "attn.qkv", d, 3 * d)
            linear(p + "attn.proj", d, d)
            for name in ("projq", "projk", "projv", "proj"):
                linear(p + "cross_attn." + name, d, d)
            norm(p + "norm2", d)
            norm(p + "norm3", d)
            linear(p + "mlp.fc1", d, m * d)
            linear(p + "mlp.fc2", m * d, d)
            norm(p + "norm_y", d)
    norm("dec_norm", d)
    L, feat = cfg.layer_dims, cfg.feature_dim
    dims_in = [e, d, d, d]
    for h in range(1, heads + 1):
        p = "downstream_head%d.dpt." % h
        for i in range(4):
            conv(p + "scratch.layer%d_rn" % (i + 1), L[i], feat, 3, bias=False)
        for i in range(1, 5):
            r = p + "scratch.refinenet%d." % i
            conv(r + "out_conv", feat, feat, 1)
            for unit in ("resConfUnit1", "resConfUnit2"):
                conv(r + unit + ".conv1", feat, feat, 3)
                conv(r + unit + ".conv2", feat, feat, 3)
        conv(p + "head.0", feat, feat // 2, 3)
        conv(p + "head.2", feat // 2, cfg.last_dim, 3)
        conv(p + "head.4", cfg.last_dim, 4, 1)
        for i in range(4):
            conv(p + "act_postprocess.%d.0" % i, dims_in[i], L[i], 1)
        # ConvTranspose2d weights are (in, out, k, k).
        shapes[p + "act_postprocess.0.1.weight"] = (L[0], L[0], 4, 4)
        shapes[p + "act_postprocess.0.1.bias"] = (L[0],)
        shapes[p + "act_postprocess.1.1.weight"] = (L[1], L[1], 2, 2)
        shapes[p + "act_postprocess.1.1.bias"] = (L[1],)
        conv(p + "act_postprocess.3.1", L[3], L[3], 3)
    return shapes


def random_parameters(cfg, seed):
    """ffloc bench's scheme: kernels uniform in +-sqrt(3 / fan_in), norm scales near 1, small biases."""
    gen = torch.Generator().manual_seed(seed)
    params = {}
    for name, shape in parameter_shapes(cfg).items():
        t = torch.empty(shape)
        if name.endswith(".bias"):
            t.uniform_(-0.02, 0.02, generator=gen)
        elif len(shape) == 1:
            t.uniform_(0.9, 1.1, generator=gen)
        else:
            fan_in = max(1, t.numel() // shape[0])
            bound = math.sqrt(3.0 / fan_in)
            t.uniform_(-bound, bound, generator=gen)
        params[name] = t
    return params


def read_safetensors(path):
    dtypes = {"F32": torch.float32, "F16": torch.float16, "BF16": torch.bfloat16, "I64": torch.int64,
              "I32": torch.int32, "U8": torch.uint8, "F64": torch.float64}
    with open(path, "rb") as f:
        data = f.read()
    (header_len,) = struct.unpack("<Q", data[:8])
    header = json.loads(data[8:8 + header_len])
    body = memoryview(data)[8 + header_len:]
    out = {}
    for name, info in header.items():
        if name == "__metadata__":
            continue
        begin, end = info["data_offsets"]
        dtype = dtypes[info["dtype"]]
        if end == begin:
            out[name] = torch.empty(info["shape"], dtype=dtype)
        else:
            out[name] = torch.frombuffer(bytearray(body[begin:end]), dtype=dtype).reshape(info["shape"])
    return out


# ---------------------------------------------------------------------------------------------
# The network.

def linear(x, p, name):
    return F.linear(x, p[name + ".weight"], p[name + ".bias"])


def layer_norm(x, p, name, eps):
    return F.layer_norm(x, (x.shape[-1],), p[name + ".weight"], p[name + ".bias"], eps)


def rope_tables(half_dim, num_positions, base):
    """cos, sin of shape (num_positions, half_dim), built in float32 like the reference."""
    inv_freq = 1.0 / (base ** (torch.arange(0, half_dim, 2).float() / half_dim))
    angles = torch.outer(torch.arange(num_positions, dtype=torch.float32), inv_freq)
    angles = torch.cat((angles, angles), dim=-1)
    return angles.cos(), angles.sin()


def rotate_half(x):
    first, second = x.chunk(2, dim=-1)
    return torch.cat((-second, first), dim=-1)


def rope_1d(t, pos, cos, sin):
    c = F.embedding(pos, cos)[:, None]
    s = F.embedding(pos, sin)[:, None]
    return t * c + rotate_half(t) * s


def rope_2d(t, pos, base):
    """t (B, heads, N, hd); pos (B, N, 2) int64 (y, x)."""
    half = t.shape[-1] // 2
    cos, sin = rope_tables(half, int(pos.max()) + 1, base)
    y, x = t.chunk(2, dim=-1)
    return torch.cat((rope_1d(y, pos[:, :, 0], cos, sin), rope_1d(x, pos[:, :, 1], cos, sin)), dim=-1)


def attend(q, k, v):
    scores = (q @ k.transpose(-2, -1)) * q.shape[-1] ** -0.5
    out = scores.softmax(dim=-1) @ v
    b, h, n, hd = out.shape
    return out.transpose(1, 2).reshape(b, n, h * hd)


def split_heads(x, heads):
    b, n, c = x.shape
    return x.reshape(b, n, heads, c // heads).permute(0, 2, 1, 3)


def self_attention(x, pos, p, name, heads, base):
    b, n, c = x.shape
    qkv = linear(x, p, name + ".qkv").reshape(b, n, 3, heads, c // heads).permute(2, 0, 3, 1, 4)
    q, k, v = qkv[0], qkv[1], qkv[2]
    return linear(attend(rope_2d(q, pos, base), rope_2d(k, pos, base), v), p, name + ".proj")


def cross_attention(x, y, xpos, ypos, p, name, heads, base):
    q = rope_2d(split_heads(linear(x, p, name + ".projq"), heads), xpos, base)
    k = rope_2d(split_heads(linear(y, p, name + ".projk"), heads), ypos, base)
    v = split_heads(linear(y, p, name + ".projv"), heads)
    return linear(attend(q, k, v), p, name + ".proj")


def mlp(x, p, name):
    return linear(F.gelu(linear(x, p, name + ".fc1")), p, name + ".fc2")


def patch_positions(batch, rows, cols):
    y = torch.arange(rows).view(rows, 1).expand(rows, cols)
    x = torch.arange(cols).view(1, cols).expand(rows, cols)
    return torch.stack((y, x), dim=-1).reshape(1, rows * cols, 2).expand(batch, -1, -1).contiguous()


def encode(img, p, cfg, trace=None, view="view1"):
    b, _, h, w = img.shape
    x = F.conv2d(img, p["patch_embed.proj.weight"], p["patch_embed.proj.bias"], stride=cfg.patch)
    x = x.flatten(2).transpose(1, 2)
    pos = patch_positions(b, h // cfg.patch, w // cfg.patch)
    record(trace, view, "patch_embed.x", x)
    record(trace, view, "patch_embed.pos", pos)
    for i in range(cfg.enc_depth):
        blk = "enc_blocks.%d." % i
        x = x + self_attention(layer_norm(x, p, blk + "norm1", cfg.eps), pos, p, blk + "attn", cfg.enc_heads,
                               cfg.rope_base)
        x = x + mlp(layer_norm(x, p, blk + "norm2", cfg.eps), p, blk + "mlp")
        record(trace, view, "enc.block%d" % i, x)
    x = layer_norm(x, p, "enc_norm", cfg.eps)
    record(trace, view, "enc.out", x)
    return x, pos


def decoder_block(x, y, xpos, ypos, p, blk, cfg):
    heads, base = cfg.dec_heads, cfg.rope_base
    x = x + self_attention(layer_norm(x, p, blk + "norm1", cfg.eps), xpos, p, blk + "attn", heads, base)
    y = layer_norm(y, p, blk + "norm_y", cfg.eps)
    x = x + cross_attention(layer_norm(x, p, blk + "norm2", cfg.eps), y, xpos, ypos, p, blk + "cross_attn", heads,
                            base)
    return x + mlp(layer_norm(x, p, blk + "norm3", cfg.eps), p, blk + "mlp")


def decode(enc1, pos1, enc2, pos2, p, cfg, trace=None):
    """Per view the DPT inputs [enc_out, f_1, ..., f_{d-1}, dec_norm(f_d)]."""
    f1 = linear(enc1, p, "decoder_embed")
    f2 = linear(enc2, p, "decoder_embed")
    record(trace, "view1", "dec.embed", f1)
    record(trace, "view2", "dec.embed", f2)
    out1, out2 = [enc1], [enc2]
    for i in range(cfg.dec_depth):
        # Both views read the other's tokens of the previous layer.
        f1, f2 = (decoder_block(f1, f2, pos1, pos2, p, "dec_blocks.%d." % i, cfg),
                  decoder_block(f2, f1, pos2, pos1, p, "dec_blocks2.%d." % i, cfg))
        record(trace, "view1", "dec.block%d" % i, f1)
        record(trace, "view2", "dec.block%d" % i, f2)
        out1.append(f1)
        out2.append(f2)
    out1[-1] = layer_norm(f1, p, "dec_norm", cfg.eps)
    out2[-1] = layer_norm(f2, p, "dec_norm", cfg.eps)
    record(trace, "view1", "dec.out", out1[-1])
    record(trace, "view2", "dec.out", out2[-1])
    return out1, out2


def conv(x, p, name, stride=1, padding=0):
    return F.conv2d(x, p[name + ".weight"], p.get(name + ".bias"), stride=stride, padding=padding)


def residual_unit(x, p, name):
    out = conv(F.relu(x), p, name + ".conv1", padding=1)
    return conv(F.relu(out), p, name + ".conv2", padding=1) + x


def upsample2(x):
    return F.interpolate(x, scale_factor=2, mode="bilinear", align_corners=True)


def fusion(p, name, first, second=None):
    out = first
    if second is not None:
        out = out + residual_unit(second, p, name + ".resConfUnit1")
    out = residual_unit(out, p, name + ".resConfUnit2")
    return conv(upsample2(out), p, name + ".out_conv")


def dpt_head(layers, h, w, p, prefix, cfg, trace=None, view="view1"):
    rows, cols = h // cfg.patch, w // cfg.patch
    maps = []
    for i, hook in enumerate(cfg.hooks):
        t = layers[hook]
        x = t.transpose(1, 2).reshape(t.shape[0], t.shape[2], rows, cols)
        x = conv(x, p, prefix + "act_postprocess.%d.0" % i)
        if i in (0, 1):
            name = prefix + "act_postprocess.%d.1" % i
            k = 4 if i == 0 else 2
            x = F.conv_transpose2d(x, p[name + ".weight"], p[name + ".bias"], stride=k)
        elif i == 3:
            x = conv(x, p, prefix + "act_postprocess.3.1", stride=2, padding=1)
        record(trace, view, "head.act_postprocess%d" % i, x)
        x = conv(x, p, prefix + "scratch.layer%d_rn" % (i + 1), padding=1)
        record(trace, view, "head.layer_rn%d" % i, x)
        maps.append(x)
    s = prefix + "scratch.refinenet"
    path = fusion(p, s + "4", maps[3])
    record(trace, view, "head.refinenet4_uncropped", path)
    path = path[:, :, :maps[2].shape[2], :maps[2].shape[3]]
    record(trace, view, "head.path4", path)
    for level in (3, 2, 1):
        path = fusion(p, s + str(level), path, maps[level - 1])
        record(trace, view, "head.path%d" % level, path)
    out = upsample2(conv(path, p, prefix + "head.0", padding=1))
    out = conv(F.relu(conv(out, p, prefix + "head.2", padding=1)), p, prefix + "head.4")
    record(trace, view, "head.raw", out)
    return out


def postprocess(raw):
    fmap = raw.permute(0, 2, 3, 1)
    xyz = fmap[..., :3]
    d = xyz.norm(dim=-1, keepdim=True)
    return xyz / d.clamp(min=1e-8) * torch.expm1(d), 1 + fmap[..., 3].exp()


def heads_forward(dec1, dec2, shape1, shape2, p, cfg, trace=None):
    raw1 = dpt_head(dec1, shape1[0], shape1[1], p, "downstream_head1.dpt.", cfg, trace, "view1")
    raw2 = dpt_head(dec2, shape2[0], shape2[1], p, "downstream_head2.dpt.", cfg, trace, "view2")
    pts1, conf1 = postprocess(raw1)
    pts2, conf2 = postprocess(raw2)
    record(trace, "view1", "pts3d", pts1)
    record(trace, "view1", "conf", conf1)
    record(trace, "view2", "pts3d_in_other_view", pts2)
    record(trace, "view2", "conf", conf2)
    return pts1, conf1, pts2, conf2


def pair_forward(img1, img2, p, cfg, trace=None):
    if img1.shape == img2.shape:
        # Same-shape pairs are encoded as one batch of 2, like the reference.
        batch_trace = {} if trace is not None else None
        enc, pos = encode(torch.cat((img1, img2)), p, cfg, batch_trace, "pair")
        enc1, enc2, pos1, pos2 = enc[:1], enc[1:], pos[:1], pos[1:]
        for name, value in (batch_trace or {}).items():
            trace["view1" + name[4:]] = value[:1]
            trace["view2" + name[4:]] = value[1:]
    else:
        enc1, pos1 = encode(img1, p, cfg, trace, "view1")
        enc2, pos2 = encode(img2, p, cfg, trace, "view2")
    dec1, dec2 = decode(enc1, pos1, enc2, pos2, p, cfg, trace)
    return heads_forward(dec1, dec2, img1.shape[2:], img2.shape[2:], p, cfg, trace)


def record(trace, view, name, value):
    if trace is not None:
        trace[view + "." + name] = value


# ---------------------------------------------------------------------------------------------
# --check

def compare(name, ours, ref, tolerance):
    if ours is None:
        return "%s: not computed" % name
    if tuple(ours.shape) != tuple(ref.shape):
        return "%s: shape %s, fixture %s" % (name, tuple(ours.shape), tuple(ref.shape))
    if not ref.is_floating_point():
        return None if torch.equal(ours.to(ref.dtype), ref) else "%s: integer tensor differs" % name
    err = (ours.double() - ref.double()).abs().max().item()
    scale = ref.double().abs().max().item()
    rel = err / scale if scale > 0 else err
    compare.worst = max(compare.worst, rel)
    return None if rel <= tolerance else "%s: relative error %.3g > %.3g" % (name, rel, tolerance)


compare.worst = 0.0


def check(folder, tolerance):
    failures = []
    keys_file = os.path.join(folder, "large_config_keys.json")
    with open(keys_file) as f:
        official = {k["name"]: tuple(k["shape"]) for k in json.load(f)["keys"] if "alias_of" not in k}
    ours = parameter_shapes(LARGE)
    if ours != official:
        missing = sorted(set(official) - set(ours))[:3]
        extra = sorted(set(ours) - set(official))[:3]
        wrong = sorted(n for n in set(ours) & set(official) if ours[n] != official[n])[:3]
        failures.append("large config parameters differ from %s: missing %s, extra %s, shapes %s"
                        % (keys_file, missing, extra, wrong))

    cfg = config_from_fixture(os.path.join(folder, "tiny_config.json"))
    params = read_safetensors(os.path.join(folder, "tiny_model.safetensors"))
    if set(params) != set(parameter_shapes(cfg)):
        failures.append("tiny_model.safetensors: the parameter names differ from the model's")

    with torch.no_grad():
        case = read_safetensors(os.path.join(folder, "case_rope_unit.safetensors"))
        for hd in (64, 16, 12):
            prefix = "hd%d." % hd
            tokens, pos = case[prefix + "tokens"], case[prefix + "pos"]
            cos, sin = rope_tables(hd // 2, case[prefix + "cos_table"].shape[0], cfg.rope_base)
            for name, value in ((prefix + "out", rope_2d(tokens, pos, cfg.rope_base)),
                                (prefix + "cos_table", cos), (prefix + "sin_table", sin)):
                failures.append(compare("case_rope_unit " + name, value, case[name], tolerance))

        for case_name in ("case_encoder_single", "case_pair_landscape", "case_pair_mixed"):
            case = read_safetensors(os.path.join(folder, case_name + ".safetensors"))
            trace = {}
            img1 = (case["view1.img_uint8"].permute(2, 0, 1)[None].float() / 255 - 0.5) / 0.5
            trace["view1.img"] = img1
            if case_name == "case_encoder_single":
                encode(img1, params, cfg, trace, "view1")
            else:
                img2 = (case["view2.img_uint8"].permute(2, 0, 1)[None].float() / 255 - 0.5) / 0.5
                trace["view2.img"] = img2
                pair_forward(img1, img2, params, cfg, trace)
            for view in ("view1", "view2"):
                if view + ".img" in trace:
                    h, w = trace[view + ".img"].shape[2:]
                    trace[view + ".true_shape"] = torch.tensor([[h, w]], dtype=torch.int32)
            for name, ref in case.items():
                if name.endswith(".img_uint8"):  # the input
                    continue
                failures.append(compare(case_name + " " + name, trace.get(name), ref, tolerance))
            print("%s: %d tensors compared" % (case_name, len(case)))
    failures = [f for f in failures if f]
    for failure in failures:
        print("FAIL", failure)
    print("worst relative error %.3g (tolerance %.3g)" % (compare.worst, tolerance))
    return 1 if failures else 0


# ---------------------------------------------------------------------------------------------
# --bench

def encoder_gflop(cfg, tokens):
    e, m = cfg.enc_dim, cfg.mlp_ratio
    return (2 * tokens * 3 * cfg.patch ** 2 * e + cfg.enc_depth * ((8 + 4 * m) * tokens * e * e + 4 * tokens * tokens * e)) * 1e-9


def time_calls(call, warmup, repeats):
    for _ in range(warmup):
        call()
    seconds = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        seconds.append(time.perf_counter() - start)
    return seconds


def median(values):
    s = sorted(values)
    n = len(s)
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def bench(args):
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    cfg = LARGE
    params = random_parameters(cfg, args.seed)
    img1 = torch.rand(1, 3, args.height, args.width) * 2 - 1
    img2 = torch.rand(1, 3, args.height, args.width) * 2 - 1
    tokens = (args.height // cfg.patch) * (args.width // cfg.patch)
    rows = []
    with torch.no_grad():
        calls = time_calls(lambda: encode(img1, params, cfg), args.warmup, args.repeats)
        rows.append(("encoder, 1 image", calls, encoder_gflop(cfg, tokens)))
        enc1, pos1 = encode(img1, params, cfg)
        enc2, pos2 = encode(img2, params, cfg)
        shape = (args.height, args.width)

        def pair():
            dec1, dec2 = decode(enc1, pos1, enc2, pos2, params, cfg)
            heads_forward(dec1, dec2, shape, shape, params, cfg)

        calls = time_calls(pair, args.warmup, args.repeats)
        rows.append(("DUSt3R decoder + 2 DPT heads, pair", calls, None))
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    for name, calls, gflop in rows:
        if args.json:
            print(json.dumps({"row": name, "dtype": "fp32", "threads": args.threads, "median_s": median(calls),
                              "calls_s": calls, "gflop": gflop, "implementation": "pytorch-eager",
                              "torch": torch.__version__, "peak_rss_mib": peak_mib}))
        else:
            print("fp32 %-40s median %.3f s  calls %s" % (name, median(calls), " ".join("%.3f" % c for c in calls)))
    if not args.json:
        print("torch %s, %d threads, peak RSS %.0f MiB" % (torch.__version__, args.threads, peak_mib))
    sys.stdout.flush()
    return 0


def main():
    if ARGS.check:
        if not os.path.isfile(os.path.join(ARGS.check, "tiny_model.safetensors")):
            print("dust3r_eager: no fixtures in %s; skipped" % ARGS.check)
            return SKIP
        return check(ARGS.check, ARGS.tolerance)
    return bench(ARGS)


if __name__ == "__main__":
    sys.exit(main())
