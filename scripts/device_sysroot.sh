#!/usr/bin/env bash
# Packs the Debian build dependencies that a lent GPU machine lacks into one archive, so that
# ffloc can be built there against the libtorch of its PyTorch (docs/training.md, "A GPU run").
#
#   scripts/device_sysroot.sh [OUT_ARCHIVE]      (default device_data/sysroot.tar.xz)
#
# The device image has CUDA, PyTorch, CMake and a compiler, but not OpenCV, Eigen, nlohmann-json,
# CLI11, GoogleTest, libjpeg or OpenBLAS, and it cannot fetch packages. The archive holds their
# headers, CMake package files and the shared libraries that OpenCV's core, imgproc, imgcodecs,
# calib3d and features2d load, taken from this Debian machine, under usr/ as on Debian; the
# CMake files of OpenCV, GoogleTest and Eigen compute their paths from where they lie, so the
# tree works from any prefix. Debian's imgcodecs also loads GDAL and GDCM (satellite and medical
# formats ffloc never reads), whose dependency trees alone are over 100 MB: they are replaced by
# stubs that define the few functions imgcodecs binds at load time, each returning 0 (imread
# calls GDALAllRegister on every machine; GDAL then opens nothing).
# On the device: tar -xJf ARCHIVE -C PREFIX, then configure with -DCMAKE_PREFIX_PATH=PREFIX/usr
# and run with LD_LIBRARY_PATH=PREFIX/usr/lib/x86_64-linux-gnu (scripts/train_on_device.sh).
set -euo pipefail

archive=$(realpath -m "${1:-device_data/sysroot.tar.xz}")
lib=/usr/lib/x86_64-linux-gnu
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
root=$work/usr
mkdir -p "$root/include" "$root/lib/x86_64-linux-gnu/cmake" "$root/share/cmake" "$root/share/eigen3"

cp -a /usr/include/opencv4 /usr/include/eigen3 /usr/include/nlohmann /usr/include/CLI \
  /usr/include/gtest /usr/include/gmock "$root/include/"
cp /usr/include/jpeglib.h /usr/include/jmorecfg.h /usr/include/jerror.h "$root/include/"
# Multiarch headers flattened: the device's compiler does not search Debian's multiarch folder
# under another prefix.
cp -L /usr/include/x86_64-linux-gnu/jconfig.h /usr/include/x86_64-linux-gnu/cblas.h \
  /usr/include/x86_64-linux-gnu/cblas_mangling.h "$root/include/"
cp -a $lib/cmake/opencv4 $lib/cmake/GTest "$root/lib/x86_64-linux-gnu/cmake/"
cp -a /usr/share/cmake/CLI11 /usr/share/cmake/nlohmann_json "$root/share/cmake/"
cp -a /usr/share/eigen3/cmake "$root/share/eigen3/"
cp -a $lib/libgtest.a $lib/libgtest_main.a $lib/libgmock.a $lib/libgmock_main.a "$root/lib/x86_64-linux-gnu/"

stubbed="libgdal.so.32 libgdcmMSFF.so.3.0 libgdcmDSED.so.3.0"
# The C library, the compiler's runtime and zlib are the device's own; its compiler's libgomp
# must win over Debian's older one.
system="libc.so.6 libm.so.6 libstdc++.so.6 libgcc_s.so.1 libpthread.so.0 libdl.so.2 librt.so.1
        ld-linux-x86-64.so.2 libz.so.1 libgomp.so.1"
declare -A seen=()
queue=(libopencv_core.so.406 libopencv_imgproc.so.406 libopencv_imgcodecs.so.406
       libopencv_calib3d.so.406 libopencv_features2d.so.406 libopencv_flann.so.406
       libjpeg.so.62 libblas.so.3)
while [ ${#queue[@]} -gt 0 ]; do
  name=${queue[0]}
  queue=("${queue[@]:1}")
  [ -z "${seen[$name]:-}" ] || continue
  seen[$name]=1
  case " $stubbed $(echo $system) " in *" $name "*) continue ;; esac
  path=$(realpath "$lib/$name")
  cp "$path" "$root/lib/x86_64-linux-gnu/$name"
  for needed in $(readelf -d "$path" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p'); do
    queue+=("$needed")
  done
done
# The names a build links with.
for name in opencv_core opencv_imgproc opencv_imgcodecs opencv_calib3d opencv_features2d opencv_flann; do
  ln -s "lib$name.so.406" "$root/lib/x86_64-linux-gnu/lib$name.so.4.6.0"
  ln -s "lib$name.so.406" "$root/lib/x86_64-linux-gnu/lib$name.so"
done
# OpenCV's CMake package checks that the file of every module it lists exists; the modules ffloc
# never links are empty placeholders.
for file in $(grep -oh 'libopencv_[a-z_0-9]*\.so\.4\.6\.0' $lib/cmake/opencv4/OpenCVModules-*.cmake | sort -u); do
  [ -e "$root/lib/x86_64-linux-gnu/$file" ] || : >"$root/lib/x86_64-linux-gnu/$file"
done
ln -s libjpeg.so.62 "$root/lib/x86_64-linux-gnu/libjpeg.so"
ln -s libblas.so.3 "$root/lib/x86_64-linux-gnu/libblas.so"

imported=$(nm -D --undefined-only $lib/libopencv_imgcodecs.so.406 | awk '{print $2}' | sed 's/@.*//' | sort)
for name in $stubbed; do
  {
    index=0
    for symbol in $(nm -D --defined-only "$lib/$name" | awk '$2 == "T" {print $3}' | sort | comm -12 - <(echo "$imported")); do
      echo "long stub$index(void) __asm__(\"$symbol\");"
      echo "long stub$index(void) { return 0; }"
      index=$((index + 1))
    done
  } >"$work/stub.c"
  gcc -shared -fPIC -O1 -Wl,-soname,"$name" -o "$root/lib/x86_64-linux-gnu/$name" "$work/stub.c"
done

mkdir -p "$(dirname "$archive")"
tar -C "$work" -cJf "$archive" usr
echo "$archive: $(du -h "$archive" | cut -f1) ($(du -sh "$root" | cut -f1) unpacked)"
