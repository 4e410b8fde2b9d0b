#!/usr/bin/env bash
# Vendors three.js for the studio page (crates/cli/studio/).
#
# Downloads the pinned npm tarball, checks it against the registry's published sha512
# integrity, and copies exactly the files the page loads (plus the licence) into ./three/.
# Re-run after changing VERSION and INTEGRITY (see README.md beside this script).
#
# Needs: bash, curl, tar, openssl (or sha512sum + base64/xxd).
set -euo pipefail

VERSION=0.187.0
# `npm view three@$VERSION dist.integrity`
INTEGRITY=sha512-Qiu7R+Cmh8CstZsY1uJOSWnVlfo7ZtNLV7mF8Jltk3LB3AtDu9cRZlcnRKkAk8Y4z6KKw35z7Y7Urd7jWY8etA==
URL="https://registry.npmjs.org/three/-/three-$VERSION.tgz"

# The files the page uses, as paths inside the tarball's package/ folder.
# (three's npm package has no minified builds since r17x: the page loads the plain ES modules;
# three.module.js imports './three.core.js', OrbitControls.js imports 'three' via the page's
# import map.)
FILES=(
  build/three.module.js
  build/three.core.js
  examples/jsm/controls/OrbitControls.js
  LICENSE
)

here=$(cd "$(dirname "$0")" && pwd)
dest="$here/three"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "downloading $URL"
curl -fsSL --retry 3 -o "$work/three.tgz" "$URL"

# npm's integrity is "sha512-" + base64 of the raw digest.
if command -v openssl >/dev/null; then
  actual="sha512-$(openssl dgst -sha512 -binary "$work/three.tgz" | base64 -w0)"
else
  actual="sha512-$(sha512sum "$work/three.tgz" | cut -d' ' -f1 | xxd -r -p | base64 -w0)"
fi
if [[ "$actual" != "$INTEGRITY" ]]; then
  echo "integrity mismatch for three@$VERSION:" >&2
  echo "  expected $INTEGRITY" >&2
  echo "  got      $actual" >&2
  exit 1
fi
echo "integrity ok ($INTEGRITY)"

tar -xzf "$work/three.tgz" -C "$work"
pkg="$work/package"
got=$(sed -n 's/^ *"version": *"\([^"]*\)".*/\1/p' "$pkg/package.json" | head -1)
if [[ "$got" != "$VERSION" ]]; then
  echo "package.json says version $got, expected $VERSION" >&2
  exit 1
fi

rm -rf "$dest"
mkdir -p "$dest"
for f in "${FILES[@]}"; do
  cp "$pkg/$f" "$dest/$(basename "$f")"
done
printf '%s\n' "three@$VERSION" "$INTEGRITY" "$URL" > "$dest/VERSION"

echo "copied into $dest:"
(cd "$dest" && sha256sum -- *)
