# syntax=docker/dockerfile:1
# reflectance serve: multi-stage build with cargo-chef (dependencies cached in their own
# layer), distroless runtime as a non-root user, the shipped models baked in.
#
#   docker build -t reflectance .
#   docker run --rm -p 8080:8080 reflectance
#
# The admin plane stays off unless a token is given (REFLECTANCE_ADMIN_TOKEN or
# --admin-token-file); to expose it, publish 8081 and set --admin-listen 0.0.0.0:8081.

ARG RUST_VERSION=1.95
FROM rust:${RUST_VERSION}-slim-bookworm AS chef
# libjpeg-turbo (the turbojpeg-sys crate builds it from its bundled source, linked
# statically) needs cmake, make and nasm at build time; the runtime image needs nothing.
RUN (command -v cmake && command -v make && command -v nasm) >/dev/null \
 || (apt-get update && apt-get install -y --no-install-recommends cmake make nasm \
     && rm -rf /var/lib/apt/lists/*)
RUN cargo install cargo-chef --locked
WORKDIR /app
# The binary is stripped below: the line tables Cargo.toml's release profile keeps for
# profiling would be compiled, linked and thrown away (as in .ci/run's build).
ENV CARGO_PROFILE_RELEASE_DEBUG=false

FROM chef AS planner
COPY . .
RUN cargo chef prepare --recipe-path recipe.json

FROM chef AS builder
COPY --from=planner /app/recipe.json recipe.json
# The binary's dependencies only (not the Python package's, a workspace member maturin builds).
RUN cargo chef cook --release --recipe-path recipe.json --bin reflectance
COPY . .
RUN cargo build --release --locked --bin reflectance \
 && strip target/release/reflectance \
 && mkdir -p /out/data

FROM gcr.io/distroless/cc-debian12:nonroot AS runtime
WORKDIR /srv
COPY --from=builder /app/target/release/reflectance /usr/local/bin/reflectance
# The shipped models only (.dockerignore leaves out what local serving or training added).
COPY models /srv/models
# The data directory of admin jobs, owned by the user the server runs as (distroless has no
# shell to create it at run time).
COPY --from=builder --chown=65532:65532 /out/data /srv/data
ENV REFLECTANCE_MODELS=/srv/models \
    REFLECTANCE_DEFAULT_MODEL=ward6 \
    REFLECTANCE_LISTEN=0.0.0.0:8080 \
    REFLECTANCE_DATA_DIR=/srv/data \
    REFLECTANCE_LOG_FORMAT=json
USER nonroot:nonroot
EXPOSE 8080
# Checks the port of REFLECTANCE_LISTEN (on loopback), so a changed port needs no change here.
HEALTHCHECK --interval=10s --timeout=3s --start-period=20s --retries=3 \
  CMD ["/usr/local/bin/reflectance", "healthcheck"]
ENTRYPOINT ["/usr/local/bin/reflectance"]
CMD ["serve"]
