#!/usr/bin/env bash
# Makes a private certificate authority and a certificate for the router, for TLS links
# between machines (docs/deployment.md). Usage, from the repository root:
#   deploy/auth/make-certs.sh ROUTER_HOST_NAME [MORE_NAMES_OR_IPS...]
# Writes deploy/auth/certs/{ca.pem,ca.key,router.pem,router.key}. Copy ca.pem to every
# machine; router.key stays on the router. Needs openssl.
set -euo pipefail
if [ $# -lt 1 ]; then
  echo "usage: $0 ROUTER_HOST_NAME [MORE_NAMES_OR_IPS...]  (e.g. $0 router.lab.example 10.0.0.5)" >&2
  exit 2
fi
out="$(dirname "$0")/certs"
mkdir -p "$out"
san=""
for name in "$@"; do
  if [[ "$name" =~ ^[0-9.]+$ || "$name" == *:* ]]; then san+="IP:$name,"; else san+="DNS:$name,"; fi
done
san="${san%,}"
openssl req -x509 -newkey rsa:2048 -nodes -days 825 -subj "/CN=highway-arena CA" \
  -keyout "$out/ca.key" -out "$out/ca.pem" 2>/dev/null
openssl req -newkey rsa:2048 -nodes -subj "/CN=$1" -keyout "$out/router.key" -out "$out/router.csr" 2>/dev/null
openssl x509 -req -in "$out/router.csr" -CA "$out/ca.pem" -CAkey "$out/ca.key" -CAcreateserial -days 825 \
  -extfile <(printf "subjectAltName=%s\nbasicConstraints=CA:FALSE\nkeyUsage=digitalSignature,keyEncipherment\nextendedKeyUsage=serverAuth" "$san") \
  -out "$out/router.pem" 2>/dev/null
rm -f "$out/router.csr" "$out/ca.srl"
chmod 600 "$out/ca.key" "$out/router.key"
echo "wrote $out/ca.pem (copy to every machine) and $out/router.pem, $out/router.key (router only) for $san"
