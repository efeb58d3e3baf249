// Vite configuration of the lapmesh viewer page: relative asset URLs, so the server can
// serve the built files from any directory.
import { defineConfig } from 'vite';

export default defineConfig({
  base: './',
  build: { chunkSizeWarningLimit: 1000, reportCompressedSize: false },
});
