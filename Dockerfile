# Multi-stage build: compile with the Rust toolchain, run on a slim Debian as a non-root user.
# Run: docker run -p 8080:8080 -v truecut-data:/data -e TRUECUT_TOKENS='s3cret admin' truecut
# (the container listens on 0.0.0.0, which truecut allows only with tokens configured).
FROM rust:1-slim-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock openapi.yaml ./
COPY src ./src
COPY assets ./assets
COPY migrations ./migrations
COPY benches ./benches
COPY tests ./tests
# The commit built, in every answer's truecut_version: docker build --build-arg
# TRUECUT_GIT_COMMIT=$(git rev-parse --short HEAD) . (empty: the package version alone).
ARG TRUECUT_GIT_COMMIT=
RUN cargo build --release --locked --bin truecut

FROM debian:bookworm-slim
RUN apt-get update \
 && apt-get install -y --no-install-recommends ca-certificates \
 && rm -rf /var/lib/apt/lists/* \
 && useradd --system --uid 10001 --home-dir /data --shell /usr/sbin/nologin truecut \
 && mkdir -p /data && chown truecut:truecut /data
COPY --from=build /src/target/release/truecut /usr/local/bin/truecut
USER truecut
VOLUME ["/data"]
EXPOSE 8080
ENV TRUECUT_ADDR=0.0.0.0:8080 TRUECUT_DATA_DIR=/data
ENTRYPOINT ["truecut"]
CMD ["serve"]
