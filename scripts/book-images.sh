#!/usr/bin/env bash
# Regenerates the book's rendered images in docs/src/images from the bundled scenes and, for the
# helmets, the Khronos models in ../shared/corpus (skipped, saying so, without it). The preview
# screenshot, the bench chart and the sky images are made by their own commands (see the book's release checklist).
#
#   bash scripts/book-images.sh            # with the release build
#   OMNICAVE=target/debug/omnicave bash scripts/book-images.sh
set -euo pipefail
cd "$(dirname "$0")/.."

if [ -z "${OMNICAVE:-}" ]; then
  cargo build --release --locked
  OMNICAVE=target/release/omnicave
fi
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
render() { "$OMNICAVE" render --config config/cave.toml "$@" >/dev/null 2>&1 || "$OMNICAVE" render --config config/cave.toml "$@"; }

echo "living room: stereo, omnistereo, omnistereo tessellated"
render --scene assets/living-room.glb --mode stereo --out "$out/stereo"
cp "$out/stereo/unfolded-anaglyph.png" docs/src/images/living-room-stereo.png
render --scene assets/living-room.glb --mode omni-onaxis --out "$out/omni"
cp "$out/omni/unfolded-anaglyph.png" docs/src/images/living-room-omni-onaxis.png
render --scene assets/living-room.glb --mode omni-onaxis --tess error:0.5 --out "$out/tess"
cp "$out/tess/unfolded-anaglyph.png" docs/src/images/living-room-omni-tessellated.png

echo "warp variants 0.3 m from the left wall"
for warp in similar-triangles intersection-point; do
  render --scene assets/living-room.glb --mode omni-onaxis --head -1.35,1.6,0 --size 640x360 \
    --warp "$warp" --out "$out/warp-$warp"
done
convert "$out/warp-similar-triangles/unfolded-anaglyph.png" \
  "$out/warp-intersection-point/unfolded-anaglyph.png" -append +repage \
  docs/src/images/warp-variants-near-wall.png

echo "panoramas"
for scene in living-room city; do
  for projection in equirectangular hammer; do
    render --view panorama --scene "assets/$scene.glb" --projection "$projection" \
      --tess error:0.5 --pano-size 1024x512 --out "$out/pano-$scene-$projection"
    cp "$out/pano-$scene-$projection/panorama.png" "docs/src/images/panorama-$scene-$projection.png"
  done
done

corpus=../shared/corpus
if [ -d "$corpus" ]; then
  echo "helmets (Khronos sample models) on a table 0.8 m ahead, stereo and tessellated omnistereo"
  for model in DamagedHelmet FlightHelmet; do
    for mode in stereo omni-offaxis; do
      render --scene "$corpus/$model/$model.gltf" --fit floor --size-m 0.6 \
        --scene-offset 0,1.2,-0.8 --head 0,1.6,0.4 --mode "$mode" --tess error:0.5 \
        --size 960x840 --out "$out/$model-$mode"
    done
    convert "$out/$model-stereo/front-left.png" "$out/$model-omni-offaxis/front-left.png" \
      +append -resize 50% +repage "docs/src/images/$model.png"
  done
else
  echo "SKIPPED helmets: $corpus not found"
fi
echo "docs/src/images regenerated"
