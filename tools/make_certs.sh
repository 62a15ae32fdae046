#!/usr/bin/env bash
# Makes a throwaway CA, a server certificate, client certificates and a
# token for a secured run (docs/security.md), with Debian's openssl:
#   tools/make_certs.sh DIR [CLIENT ...]
# DIR/ca.pem            the CA every process trusts (--tls_ca)
# DIR/ca/ca.key         its key, in a subfolder so that `kubectl create secret
#                       --from-file=DIR` (top-level files only) leaves it out
# DIR/server.pem, .key  the servers' certificate (--tls_cert, --tls_key); its
#                       names: localhost, 127.0.0.1, learner, reward-server,
#                       reward_server, and any in $IMCA_CERT_NAMES (comma list)
# DIR/<CLIENT>.pem, .key  one client certificate per CLIENT (CN=CLIENT), for
#                       mutual TLS (default: one named "actor")
# DIR/token             a random bearer token (--token_file)
# Keys are EC P-256, certificates valid for 30 days. Files are mode 600.
set -euo pipefail
dir="${1:?usage: make_certs.sh DIR [CLIENT ...]}"
shift
clients=("$@")
((${#clients[@]})) || clients=(actor)
mkdir -p "$dir"
umask 077
cd "$dir"

key() { openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$1" 2>/dev/null; }

mkdir -p ca
key ca/ca.key
openssl req -x509 -new -key ca/ca.key -sha256 -days 30 -subj "/CN=imca test CA" \
  -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
  -out ca.pem 2>/dev/null

sign() {  # sign NAME CN EXTFILE
  key "$1.key"
  openssl req -new -key "$1.key" -subj "/CN=$2" -out "$1.csr" 2>/dev/null
  openssl x509 -req -in "$1.csr" -CA ca.pem -CAkey ca/ca.key -CAcreateserial -days 30 -sha256 \
    -extfile "$3" -out "$1.pem" 2>/dev/null
  rm -f "$1.csr"
}

sans="DNS:localhost,IP:127.0.0.1,DNS:learner,DNS:reward-server,DNS:reward_server"
IFS=',' read -r -a extra <<<"${IMCA_CERT_NAMES:-}"
for name in "${extra[@]}"; do [[ -n $name ]] && sans+=",DNS:$name"; done
printf 'subjectAltName=%s\nextendedKeyUsage=serverAuth\nbasicConstraints=CA:FALSE\n' "$sans" >server.ext
sign server localhost server.ext
printf 'extendedKeyUsage=clientAuth\nbasicConstraints=CA:FALSE\n' >client.ext
for client in "${clients[@]}"; do sign "$client" "$client" client.ext; done
rm -f server.ext client.ext ca.srl
openssl rand -hex 32 >token
