#include "common/rpc/transport.h"

#include <sys/stat.h>

#include <cstdio>

#include "absl/strings/ascii.h"
#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "common/base/atomic_file.h"

namespace imca {
namespace {

absl::StatusOr<std::string> ReadPem(const std::string& path, absl::string_view flag) {
  absl::StatusOr<std::string> text = ReadFile(path, "PEM file");
  if (!text.ok()) return absl::InvalidArgumentError(absl::StrCat(flag, ": ", text.status().message()));
  if (!absl::StrContains(*text, "-----BEGIN ")) {
    return absl::InvalidArgumentError(absl::StrCat(flag, ": '", path, "' holds no PEM block"));
  }
  return text;
}

struct PemPair {
  std::string cert, key;
};

// The certificate chain and key of --tls_cert and --tls_key.
absl::StatusOr<PemPair> ReadPemPair(const TransportConfig& config) {
  absl::StatusOr<std::string> cert = ReadPem(config.tls_cert, "--tls_cert");
  if (!cert.ok()) return cert.status();
  absl::StatusOr<std::string> key = ReadPem(config.tls_key, "--tls_key");
  if (!key.ok()) return key.status();
  return PemPair{*std::move(cert), *std::move(key)};
}

bool ConstantTimeEquals(absl::string_view a, absl::string_view b) {
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  const size_t n = std::max(a.size(), b.size());
  for (size_t i = 0; i < n; ++i) {
    diff |= static_cast<unsigned char>((i < a.size() ? a[i] : 0) ^ (i < b.size() ? b[i] : 0));
  }
  return diff == 0;
}

constexpr char kBearer[] = "Bearer ";

// Checks "authorization: Bearer <token>" on every call but health checks;
// the token is consumed, so no handler ever sees it.
class TokenAuthProcessor final : public grpc::AuthMetadataProcessor {
 public:
  explicit TokenAuthProcessor(std::shared_ptr<TokenFile> tokens) : tokens_(std::move(tokens)) {}

  bool IsBlocking() const override { return false; }

  grpc::Status Process(const InputMetadata& metadata, grpc::AuthContext*, OutputMetadata* consumed,
                       OutputMetadata*) override {
    auto path = metadata.find(":path");
    if (path != metadata.end() &&
        absl::StartsWith(absl::string_view(path->second.data(), path->second.size()), kHealthServicePrefix)) {
      return grpc::Status::OK;
    }
    auto auth = metadata.find(kAuthorizationKey);
    if (auth == metadata.end()) {
      return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                          "no token: the call carries no 'authorization: Bearer' metadata (client --token_file)");
    }
    const absl::string_view value(auth->second.data(), auth->second.size());
    if (!absl::StartsWith(value, kBearer) || !tokens_->Accepts(value.substr(sizeof(kBearer) - 1))) {
      return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                          "token not accepted (it is not in the server's --token_file)");
    }
    consumed->emplace(kAuthorizationKey, std::string(value));
    return grpc::Status::OK;
  }

 private:
  std::shared_ptr<TokenFile> tokens_;
};

class TokenPlugin final : public grpc::MetadataCredentialsPlugin {
 public:
  explicit TokenPlugin(std::shared_ptr<TokenFile> tokens) : tokens_(std::move(tokens)) {}

  bool IsBlocking() const override { return false; }
  const char* GetType() const override { return "imca-bearer-token"; }

  grpc::Status GetMetadata(grpc::string_ref, grpc::string_ref, const grpc::AuthContext&,
                           std::multimap<grpc::string, grpc::string>* metadata) override {
    metadata->emplace(kAuthorizationKey, absl::StrCat(kBearer, tokens_->First()));
    return grpc::Status::OK;
  }

 private:
  std::shared_ptr<TokenFile> tokens_;
};

}  // namespace

std::string TransportSummary(const TransportConfig& config, bool server) {
  const bool tls = server ? config.server_tls() : config.client_tls();
  const bool mutual = server ? config.require_client_cert : config.client_tls() && config.server_tls();
  std::string summary = mutual ? "mutual TLS" : tls ? "TLS" : "plaintext";
  if (!config.token_file.empty()) summary += ", token";
  return summary;
}

absl::Status ValidateServerTransport(const TransportConfig& config) {
  if (config.tls_cert.empty() != config.tls_key.empty()) {
    return absl::InvalidArgumentError("--tls_cert and --tls_key go together (the server's certificate and key)");
  }
  if (!config.tls_ca.empty() && !config.server_tls()) {
    return absl::InvalidArgumentError(
        "--tls_ca on a server needs --tls_cert and --tls_key (it names the CA of client certificates)");
  }
  if (config.require_client_cert && (!config.server_tls() || config.tls_ca.empty())) {
    return absl::InvalidArgumentError(
        "--tls_client_auth needs --tls_cert, --tls_key and --tls_ca (the CA that signs client certificates)");
  }
  if (!config.token_file.empty() && !config.server_tls()) {
    return absl::InvalidArgumentError(
        "--token_file needs --tls_cert and --tls_key: gRPC carries tokens only over TLS");
  }
  return absl::OkStatus();
}

absl::Status ValidateClientTransport(const TransportConfig& config) {
  if (config.tls_cert.empty() != config.tls_key.empty()) {
    return absl::InvalidArgumentError("--tls_cert and --tls_key go together (the client certificate and key)");
  }
  if (!config.client_tls() && (config.server_tls() || !config.token_file.empty() ||
                               !config.tls_server_name.empty())) {
    return absl::InvalidArgumentError(
        "--tls_cert, --token_file and --tls_server_name need --tls_ca (the CA that signs the servers' "
        "certificates): gRPC carries tokens only over TLS");
  }
  return absl::OkStatus();
}

absl::StatusOr<std::shared_ptr<TokenFile>> TokenFile::Open(const std::string& path) {
  std::shared_ptr<TokenFile> file(new TokenFile(path));
  absl::MutexLock lock(&file->mu_);
  if (absl::Status loaded = file->Load(); !loaded.ok()) return loaded;
  file->checked_ = absl::Now();
  return file;
}

absl::Status TokenFile::Load() {
  struct stat info {};
  if (stat(path_.c_str(), &info) != 0) {
    return absl::InvalidArgumentError(absl::StrCat("--token_file: cannot read token file '", path_, "'"));
  }
  const int64_t mtime_ns = int64_t{info.st_mtim.tv_sec} * 1000000000 + info.st_mtim.tv_nsec;
  if (mtime_ns == mtime_ns_ && info.st_size == size_ && !tokens_.empty()) return absl::OkStatus();
  absl::StatusOr<std::string> text = ReadFile(path_, "token file");
  if (!text.ok()) return absl::InvalidArgumentError(absl::StrCat("--token_file: ", text.status().message()));
  std::vector<std::string> tokens;
  int line_number = 0;
  for (absl::string_view line : absl::StrSplit(*text, '\n')) {
    ++line_number;
    line = absl::StripAsciiWhitespace(line);
    if (line.empty()) continue;
    bool printable = line.size() >= 16 && line.size() <= 4096;
    for (char c : line) printable = printable && c > ' ' && c < 127;
    if (!printable) {
      return absl::InvalidArgumentError(absl::StrCat("--token_file: '", path_, "' line ", line_number,
                                                     ": a token is 16-4096 printable characters without spaces"));
    }
    tokens.emplace_back(line);
  }
  if (tokens.empty()) {
    return absl::InvalidArgumentError(absl::StrCat("--token_file: '", path_, "' holds no token"));
  }
  tokens_ = std::move(tokens);
  mtime_ns_ = mtime_ns;
  size_ = info.st_size;
  warned_ = false;
  return absl::OkStatus();
}

void TokenFile::MaybeReload() {
  const absl::Time now = absl::Now();
  if (now - checked_ < absl::Seconds(1)) return;
  checked_ = now;
  if (absl::Status loaded = Load(); !loaded.ok() && !warned_) {
    warned_ = true;
    std::fprintf(stderr, "%s; keeping the tokens read before\n", std::string(loaded.message()).c_str());
  }
}

std::string TokenFile::First() {
  absl::MutexLock lock(&mu_);
  MaybeReload();
  return tokens_.front();
}

bool TokenFile::Accepts(absl::string_view presented) {
  absl::MutexLock lock(&mu_);
  MaybeReload();
  bool accepted = false;
  for (const std::string& token : tokens_) accepted |= ConstantTimeEquals(token, presented);
  return accepted;
}

absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> MakeServerCredentials(const TransportConfig& config) {
  if (!config.server_tls()) return grpc::InsecureServerCredentials();
  grpc::SslServerCredentialsOptions options(config.require_client_cert
                                                ? GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY
                                                : GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE);
  absl::StatusOr<PemPair> pem = ReadPemPair(config);
  if (!pem.ok()) return pem.status();
  options.pem_key_cert_pairs.push_back({std::move(pem->key), std::move(pem->cert)});
  if (!config.tls_ca.empty()) {
    absl::StatusOr<std::string> ca = ReadPem(config.tls_ca, "--tls_ca");
    if (!ca.ok()) return ca.status();
    options.pem_root_certs = *std::move(ca);
  }
  std::shared_ptr<grpc::ServerCredentials> credentials = grpc::SslServerCredentials(options);
  if (!config.token_file.empty()) {
    absl::StatusOr<std::shared_ptr<TokenFile>> tokens = TokenFile::Open(config.token_file);
    if (!tokens.ok()) return tokens.status();
    credentials->SetAuthMetadataProcessor(std::make_shared<TokenAuthProcessor>(*std::move(tokens)));
  }
  return credentials;
}

absl::StatusOr<std::shared_ptr<grpc::ChannelCredentials>> MakeChannelCredentials(const TransportConfig& config) {
  if (!config.client_tls()) return grpc::InsecureChannelCredentials();
  grpc::SslCredentialsOptions options;
  absl::StatusOr<std::string> ca = ReadPem(config.tls_ca, "--tls_ca");
  if (!ca.ok()) return ca.status();
  options.pem_root_certs = *std::move(ca);
  if (config.server_tls()) {
    absl::StatusOr<PemPair> pem = ReadPemPair(config);
    if (!pem.ok()) return pem.status();
    options.pem_cert_chain = std::move(pem->cert);
    options.pem_private_key = std::move(pem->key);
  }
  std::shared_ptr<grpc::ChannelCredentials> credentials = grpc::SslCredentials(options);
  if (!config.token_file.empty()) {
    absl::StatusOr<std::shared_ptr<TokenFile>> tokens = TokenFile::Open(config.token_file);
    if (!tokens.ok()) return tokens.status();
    credentials = grpc::CompositeChannelCredentials(
        credentials, grpc::MetadataCredentialsFromPlugin(std::make_unique<TokenPlugin>(*std::move(tokens))));
  }
  return credentials;
}

std::string PeerIdentity(const grpc::ServerContext& context) {
  std::shared_ptr<const grpc::AuthContext> auth = context.auth_context();
  if (auth != nullptr) {
    for (const grpc::string_ref& name : auth->FindPropertyValues("x509_common_name")) {
      return absl::StrCat("certificate CN=", absl::CHexEscape(absl::string_view(name.data(), name.size())), ", ",
                          context.peer());
    }
  }
  return absl::StrCat("no client certificate, ", context.peer());
}

bool IsRefusal(const absl::Status& status) {
  return absl::IsUnauthenticated(status) || absl::IsPermissionDenied(status);
}

bool LooksLikeTlsFailure(const absl::Status& status) {
  if (!absl::IsUnavailable(status)) return false;
  const absl::string_view m = status.message();
  return absl::StrContains(m, "andshake") || absl::StrContains(m, "SSL") || absl::StrContains(m, "ertificate") ||
         absl::StrContains(m, "Peer name") || absl::StrContains(m, "Socket closed");
}

std::string DescribeRpcFailure(absl::string_view what, const absl::Status& status, bool tls) {
  if (IsRefusal(status)) {
    return absl::StrCat(what, " refused this client's credentials (", absl::StatusCodeToString(status.code()),
                        ": ", status.message(), "); check --token_file");
  }
  if (LooksLikeTlsFailure(status)) {
    return tls ? absl::StrCat("TLS handshake with the ", what, " failed or the connection was closed (",
                              status.message(), "); check --tls_ca, --tls_cert/--tls_key and --tls_server_name "
                              "against the server's certificate and whether it requires a client certificate")
               : absl::StrCat(what, ": the connection was closed (", status.message(),
                              "); if the server runs TLS, this client needs --tls_ca (a TLS server closes "
                              "plaintext connections)");
  }
  return absl::StrCat(what, ": ", absl::StatusCodeToString(status.code()), ": ", status.message());
}

}  // namespace imca
