# Helpers for the `setup` scripts of the bad-input catalogue (bash + coreutils only, no python).
# run_case.sh sources this file before a case's `setup`, in the case's work folder $WORK, with
# BIN (the built apps), CASE (the case folder), WORK and FIX (tests/bad_inputs/fixtures) set.

# Little-endian binary integers, as bytes on stdout.
le32() {
  local n=$1 b0 b1 b2 b3
  printf -v b0 %02x $((n & 255)); printf -v b1 %02x $(((n >> 8) & 255))
  printf -v b2 %02x $(((n >> 16) & 255)); printf -v b3 %02x $(((n >> 24) & 255))
  printf "\\x$b0\\x$b1\\x$b2\\x$b3"
}
le64() { le32 $(($1 & 0xffffffff)); le32 $((($1 >> 32) & 0xffffffff)); }

# patch FILE OFFSET BYTES: overwrites bytes at OFFSET (BYTES in printf syntax, e.g. '\xff\x00').
patch() { printf "$3" | dd of="$1" bs=1 seek="$2" conv=notrunc status=none; }

# truncate_to FILE N: keeps the first N bytes of FILE.
truncate_to() { head -c "$2" "$1" > "$1.cut" && mv "$1.cut" "$1"; }

# 32-bit floats (little-endian bytes, printf escapes) for make_exr and patches.
F_ONE='\x00\x00\x80\x3f'     # 1.0
F_HALF='\x00\x00\x00\x3f'    # 0.5
F_ZERO='\x00\x00\x00\x00'    # 0.0
F_NAN='\x00\x00\xc0\x7f'     # quiet NaN
F_INF='\x00\x00\x80\x7f'     # +infinity
F_NEG='\x00\x00\x00\xbf'     # -0.5

# make_exr FILE W H VALUE [SPECIAL U V]: an uncompressed scanline OpenEXR image with one FLOAT
# channel "Y" (OpenCV reads it as a 1-channel 32-bit float image: float depth in metres), every
# pixel VALUE except pixel (U, V) = SPECIAL when given.
make_exr() {
  local file=$1 w=$2 h=$3 value=$4 special=${5:-} su=${6:--1} sv=${7:--1}
  local y u row="" special_row="" header_size chunk=$((8 + 4 * w))
  {
    printf '\x76\x2f\x31\x01\x02\x00\x00\x00'  # magic, version 2 (single-part scanline)
    printf 'channels\0chlist\0'; le32 19; printf 'Y\0'; le32 2; printf '\0\0\0\0'; le32 1; le32 1; printf '\0'
    printf 'compression\0compression\0'; le32 1; printf '\0'  # NO_COMPRESSION
    printf 'dataWindow\0box2i\0'; le32 16; le32 0; le32 0; le32 $((w - 1)); le32 $((h - 1))
    printf 'displayWindow\0box2i\0'; le32 16; le32 0; le32 0; le32 $((w - 1)); le32 $((h - 1))
    printf 'lineOrder\0lineOrder\0'; le32 1; printf '\0'
    printf 'pixelAspectRatio\0float\0'; le32 4; printf "$F_ONE"
    printf 'screenWindowCenter\0v2f\0'; le32 8; printf "$F_ZERO$F_ZERO"
    printf 'screenWindowWidth\0float\0'; le32 4; printf "$F_ONE"
    printf '\0'
  } > "$file"
  header_size=$(stat -c %s "$file")
  for ((u = 0; u < w; ++u)); do
    row+=$value
    if [ -n "$special" ] && [ "$u" -eq "$su" ]; then special_row+=$special; else special_row+=$value; fi
  done
  {
    for ((y = 0; y < h; ++y)); do le64 $((header_size + 8 * h + y * chunk)); done
    for ((y = 0; y < h; ++y)); do
      le32 "$y"; le32 $((4 * w))
      if [ "$y" -eq "$sv" ]; then printf "$special_row"; else printf "$row"; fi
    done
  } >> "$file"
}

# synth_seq DIR [FRAMES]: a small synthetic TUM sequence (32x24 pixels, FRAMES frames, default 2:
# rgb/*.png, rgb/*.exr, depth/*.png, rgb.txt, depth.txt, groundtruth.txt, intrinsics.txt,
# mesh_gt.ply, scene.json).
synth_seq() { "$BIN/genscene-synth" --frames "${2:-2}" --size 32x24 --spp 4 --out "$1" > /dev/null 2>&1; }

# fused_ws DIR: a workspace after fusion (input/ from synth_seq, tsdf.gsv, trajectory.txt,
# keyframes/, fusion.json).
fused_ws() { synth_seq "$1/input" && "$BIN/genscene-fuse" --input "$1/input" --voxel-size 0.04 --truncation 0.12 "$1" > /dev/null 2>&1; }

# chain_ws DIR: a complete small workspace, stage by stage (fused_ws, then genscene-mesh,
# genscene-texture, genscene-albedo): mesh.ply, texture.mcol/.ply/.json, albedo.mcol/.ply/.json.
chain_ws() {
  fused_ws "$1" && "$BIN/genscene-mesh" "$1" > /dev/null 2>&1 &&
    "$BIN/genscene-texture" "$1" > /dev/null 2>&1 && "$BIN/genscene-albedo" "$1" > /dev/null 2>&1
}

# ply_header FORMAT VERTICES FACES: the header of a PLY with float x/y/z vertices and uchar/int
# vertex_indices faces (FORMAT ascii, binary_little_endian or binary_big_endian).
ply_header() {
  printf 'ply\nformat %s 1.0\ncomment bad-input catalogue\nelement vertex %s\nproperty float x\nproperty float y\nproperty float z\nelement face %s\nproperty list uchar int vertex_indices\nend_header\n' "$1" "$2" "$3"
}
